// Small vector and matrix aliases over GLM, for any scalar of the generic path
// (float, double, Dual, Var; the AD glue is in ad/glm.hpp).
#pragma once

#include <glm/glm.hpp>

namespace difftrans {

template <class S> using Vec2 = glm::vec<2, S, glm::defaultp>;
template <class S> using Vec3 = glm::vec<3, S, glm::defaultp>;
template <class S> using Vec4 = glm::vec<4, S, glm::defaultp>;
template <class S> using Mat3 = glm::mat<3, 3, S, glm::defaultp>;
template <class S> using Mat4 = glm::mat<4, 4, S, glm::defaultp>;

using Vec2f = Vec2<float>;
using Vec3f = Vec3<float>;
using Vec3d = Vec3<double>;
using Vec2i = glm::ivec2;
using Vec3i = glm::ivec3;

}  // namespace difftrans
