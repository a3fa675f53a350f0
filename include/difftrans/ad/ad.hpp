// Everything of the scalar layer: Dual, Tape/Var, math overloads, GLM glue.
#pragma once

#include "difftrans/ad/dual.hpp"
#include "difftrans/ad/glm.hpp"
#include "difftrans/ad/math.hpp"
#include "difftrans/ad/params.hpp"
#include "difftrans/ad/tape.hpp"
#include "difftrans/ad/traits.hpp"
