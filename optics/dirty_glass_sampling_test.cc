// SPDX-License-Identifier: Apache-2.0
// Chi-square test of the HG-based sampling of the Gu layer against its reported density
// (minimum expected count 5, significance 0.01), for index-matched and refractive layers, from
// the air and from the glass.
#include "thinslab/optics/dirty_glass_sampling.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "thinslab/optics/sphere_test_util.h"

namespace thinslab {
namespace {

struct Case {
  double n1, n2, n3, g;
  double theta_i_deg;
  bool from_below;
};

TEST(DirtyGlassSampling, SampledDirectionsFollowThePdf) {
  const Case cases[] = {
      {1.0, 1.0, 1.0, 0.5, 30, false},   // Index-matched: plain HG about -wi.
      {1.0, 1.5, 1.5, 0.9, 40, false},   // Lipid on glass, from the air.
      {1.0, 1.5, 1.5, 0.5, 20, true},    // Lipid on glass, from the glass (TIR at the air face).
      {1.0, 1.5, 1.5, -0.6, 60, false},  // Back-scattering layer.
  };
  const int n_z = 40, n_phi = 40, samples = 400000;
  for (const Case& c : cases) {
    DirtyGlassLayer<double> layer;
    layer.n1 = c.n1;
    layer.n2 = c.n2;
    layer.n3 = c.n3;
    layer.g = c.g;
    const double th = c.theta_i_deg * kPi / 180;
    const Eigen::Vector3d wi(std::sin(th), 0, c.from_below ? -std::cos(th) : std::cos(th));
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> uni(0, 1);
    std::vector<double> observed(n_z * n_phi, 0), expected(n_z * n_phi, 0);
    int escaped = 0;
    for (int k = 0; k < samples; ++k) {
      Eigen::Vector3d wo;
      double pdf;
      if (!SampleLayerScatteredDirection(layer, wi, uni(rng), uni(rng), &wo, &pdf)) continue;
      ++escaped;
      ASSERT_NEAR(pdf, LayerScatteredDirectionPdf(layer, wi, wo), 1e-9 * pdf);
      const int iz = std::min(n_z - 1, static_cast<int>((wo.z() + 1) / 2 * n_z));
      double phi = std::atan2(wo.y(), wo.x());
      if (phi < 0) phi += 2 * kPi;
      const int ip = std::min(n_phi - 1, static_cast<int>(phi / (2 * kPi) * n_phi));
      observed[iz * n_phi + ip] += 1;
    }
    // Expected counts: the density integrated over each (z, phi) cell (d omega = dz dphi).
    double total_pdf = 0;
    for (int iz = 0; iz < n_z; ++iz) {
      for (int ip = 0; ip < n_phi; ++ip) {
        const double z0 = -1 + 2.0 * iz / n_z, z1 = -1 + 2.0 * (iz + 1) / n_z;
        const double p0 = 2 * kPi * ip / n_phi, p1 = 2 * kPi * (ip + 1) / n_phi;
        const double integral = testing::Integrate2D(
            [&](double z, double phi) {
              const double r = std::sqrt(std::max(0.0, 1 - z * z));
              return LayerScatteredDirectionPdf(layer, wi, Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), z));
            },
            z0, z1, p0, p1, {}, {}, 1e-7, 1e-5);
        expected[iz * n_phi + ip] = samples * integral;
        total_pdf += integral;
      }
    }
    // The density integrates to the escaping fraction.
    EXPECT_NEAR(total_pdf, static_cast<double>(escaped) / samples, 5e-3) << "g " << c.g;
    const testing::ChiSquareResult chi = testing::PooledChiSquare(observed, expected);
    EXPECT_EQ(chi.observed_in_empty_cells, 0) << chi.ToString();
    EXPECT_GT(chi.p_value, 0.01) << "n2 " << c.n2 << " g " << c.g << " theta " << c.theta_i_deg << ": "
                                 << chi.ToString();
  }
}

}  // namespace
}  // namespace thinslab
