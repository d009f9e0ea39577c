// Links the installed tirstrain::model and checks one closed form: inside the stick zone the surface moves
// by the rigid shift delta_x = 3 mu P (2 - nu) / (16 G a) (1 - (1 - Q/(mu P))^(2/3)) (Johnson 1985 §7.2).
#include <cmath>
#include <cstdio>

#include "core/version.hpp"
#include "model/cattaneo_mindlin.hpp"

int main() {
  const tirstrain::model::CattaneoMindlinParams p{.normal_N = 1.0,
                                                  .tangential_N = 0.3,
                                                  .radius_m = 0.01,
                                                  .young_Pa = 1.0e6,
                                                  .poisson = 0.4,
                                                  .friction = 1.0};
  const tirstrain::model::CattaneoMindlin cm(p);
  const double a = cm.hertz().contact_radius_m;
  const double g = p.young_Pa / (2.0 * (1.0 + p.poisson));
  const double expected =
      3.0 * p.normal_N * (2.0 - p.poisson) / (16.0 * g * a) * (1.0 - std::pow(0.7, 2.0 / 3.0));
  const double ux = cm.displacement_m(0.0, 0.0).x;
  const bool ok = std::abs(ux - expected) <= 1e-9 * expected;
  std::printf("tirstrain %s: ux(0, 0) = %.9g m, closed form %.9g m: %s\n", tirstrain::kVersion, ux, expected,
              ok ? "ok" : "MISMATCH");
  return ok ? 0 : 1;
}
