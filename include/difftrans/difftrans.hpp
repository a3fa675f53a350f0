// difftrans umbrella header: the scalar types, the GLM glue and the generic
// optics. Heavier parts (Embree, Eigen, CUDA) are included from their own folders.
#pragma once

#include "difftrans/ad/ad.hpp"
#include "difftrans/core/constants.hpp"
#include "difftrans/core/platform.hpp"
#include "difftrans/core/vec.hpp"
#include "difftrans/optics/optics.hpp"
