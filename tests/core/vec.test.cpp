// Vector aliases: the right GLM types for each scalar.
#include "support/ad_check.hpp"

using namespace dt_test;

static_assert(std::is_same_v<Vec3f, glm::vec3>);
static_assert(std::is_same_v<Vec3<double>, glm::dvec3>);
static_assert(Vec3<ad::Var<float>>::length() == 3);

TEST_CASE("aliases behave as GLM vectors") {
  const Vec3f a(1, 0, 0), b(0, 1, 0);
  CHECK(glm::cross(a, b) == Vec3f(0, 0, 1));
  const Mat3<double> m(2.0);
  CHECK((m * Vec3d(1, 2, 3)) == Vec3d(2, 4, 6));
}
