// Everything of the render layer on the host: tracer, host scene, passes,
// adaptive sampling, silhouettes, whole views.
#pragma once

#include "difftrans/render/adaptive.hpp"
#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/passes.hpp"
#include "difftrans/render/raster.hpp"
#include "difftrans/render/silhouette.hpp"
#include "difftrans/render/tracer.hpp"
#include "difftrans/render/views.hpp"
