// Everything of the render layer on the host: tracer, host scene, passes.
#pragma once

#include "difftrans/render/host_scene.hpp"
#include "difftrans/render/passes.hpp"
#include "difftrans/render/tracer.hpp"
