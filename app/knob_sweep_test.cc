// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/knob_sweep.h"

#include <gtest/gtest.h>

namespace thinslab {
namespace {

SweepPoint Point(const std::string& method, double seconds, double error) {
  SweepPoint p;
  p.method = method;
  p.knob = "k";
  p.value = std::to_string(seconds);
  p.seconds = seconds;
  p.error = error;
  return p;
}

TEST(MarkParetoFront, KeepsExactlyTheUndominatedPointsPerMethod) {
  std::vector<SweepPoint> points = {
      Point("a", 1, 0.5),   // Front: fastest.
      Point("a", 2, 0.3),   // Front.
      Point("a", 2, 0.4),   // Dominated by (2, 0.3): same time, worse error.
      Point("a", 3, 0.3),   // Dominated by (2, 0.3): slower, same error.
      Point("a", 5, 0.1),   // Front: most accurate.
      Point("a", 6, 0.2),   // Dominated.
      Point("a", 0.5, -1),  // Unscored: never on the front, dominates nothing.
      Point("b", 10, 0.9),  // Another method: its own front, not dominated by method a.
  };
  MarkParetoFront(&points);
  const bool expected[] = {true, true, false, false, true, false, false, true};
  for (size_t k = 0; k < points.size(); ++k) EXPECT_EQ(points[k].pareto, expected[k]) << "point " << k;
}

TEST(MarkParetoFront, IdenticalPointsBothStay) {
  std::vector<SweepPoint> points = {Point("a", 1, 0.2), Point("a", 1, 0.2)};
  MarkParetoFront(&points);
  EXPECT_TRUE(points[0].pareto);
  EXPECT_TRUE(points[1].pareto);
}

TEST(SweepCsv, QuotesLabelsWithCommasAndQuotes) {
  SweepPoint p = Point("dmf", 1, 0.2);
  p.value = "5 tabulated, \"every\" point";
  const std::string csv = SweepCsv({p});
  EXPECT_NE(csv.find(",\"5 tabulated, \"\"every\"\" point\","), std::string::npos) << csv;
}

TEST(WriteSweepChart, NoScoredPointIsAnErrorNamingTheFile) {
  const Status s = WriteSweepChart("/tmp/never_written.png", {Point("tau", 1, -1)}, "tau", "t", "e");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("/tmp/never_written.png"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace thinslab
