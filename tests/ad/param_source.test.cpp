// Parameter sources: a differentiable source reads through the reader, a
// frozen one as constants that record nothing on a tape.
#include "support/ad_check.hpp"

#include "difftrans/ad/param_source.hpp"

using namespace dt_test;
namespace sc = difftrans::ad;

TEST_CASE("frozen and differentiable sources") {
  const float values[6] = {1, 2, 3, 4, 5, 6};
  float grad[6] = {0, 0, 0, 0, 0, 0};
  ad::ParamSet set;
  set.buffers[2].values = values;
  set.buffers[2].size = 6;
  set.buffers[2].gradient = grad;
  ad::Tape<float> tape(64);
  ad::LeafRecord log[8];
  ad::ParamReader<ad::Var<float>> reader(&set, &tape, log, 8);
  const sc::ParamSource frozen{values, 6, -1}, live{values, 6, 2};
  CHECK_FALSE(frozen.differentiable());
  CHECK(live.differentiable());
  const Vec3<ad::Var<float>> a = sc::load3<ad::Var<float>>(reader, frozen, 1);
  CHECK(a.z.value == 6.0f);
  CHECK(a.x.is_constant());
  CHECK(reader.size() == 0);  // frozen reads record nothing
  const Vec3<ad::Var<float>> b = sc::load3<ad::Var<float>>(reader, live, 0);
  CHECK(reader.size() == 3);
  tape.backward(b.x * b.y + b.z * a.x);  // d/d(v0, v1, v2) = (v1, v0, a.x)
  reader.scatter();
  CHECK(grad[0] == 2.0f);
  CHECK(grad[1] == 1.0f);
  CHECK(grad[2] == 4.0f);
  CHECK(grad[3] == 0.0f);
}
