// Everything of the scene layer: camera, environment map, absorption field,
// triangle mesh, and the parameter sources they read their unknowns from.
#pragma once

#include "difftrans/scene/absorption.hpp"
#include "difftrans/scene/camera.hpp"
#include "difftrans/scene/envmap.hpp"
#include "difftrans/scene/mesh.hpp"
#include "difftrans/ad/param_source.hpp"
