// The run histograms of the nodes' compute time: percentiles at the bin resolution asked for
// (1 us for latencies, 0.1 us for the split of a node's compute into library, node and DDS write).
#include <gtest/gtest.h>

#include "poise/node/compute_stats.hpp"

namespace {

using poise::node::LatencyHistogram;

TEST(ComputeStats, HistogramPercentilesAreUpperBinEdges) {
  LatencyHistogram us(1000);  // 1 us bins
  for (double v : {1.23, 2.5, 2.6, 7.01})
    us.add(v);
  EXPECT_DOUBLE_EQ(us.percentile(0.5), 3.0);   // 2.5 lies in [2, 3)
  EXPECT_DOUBLE_EQ(us.percentile(1.0), 7.01);  // capped at the exact maximum
  EXPECT_DOUBLE_EQ(us.mean(), (1.23 + 2.5 + 2.6 + 7.01) / 4);

  LatencyHistogram fine(1000, 0.1);  // 0.1 us bins
  for (double v : {1.23, 2.55, 2.66, 7.01})
    fine.add(v);
  EXPECT_NEAR(fine.percentile(0.25), 1.3, 1e-9);
  EXPECT_NEAR(fine.percentile(0.5), 2.6, 1e-9);  // 2.55 lies in [2.5, 2.6)
  EXPECT_NEAR(fine.percentile(0.75), 2.7, 1e-9);
  EXPECT_EQ(fine.count(), 4u);
}

TEST(ComputeStats, HistogramKeepsValuesBeyondItsRangeInTheLastBin) {
  LatencyHistogram h(10, 0.1);
  h.add(-1.0);  // negative (a clock step): counted as 0
  h.add(5.05);
  h.add(1e6);  // beyond the range: last bin, exact maximum kept
  EXPECT_EQ(h.count(), 3u);
  EXPECT_DOUBLE_EQ(h.max(), 1e6);
  EXPECT_NEAR(h.percentile(0.3), 0.1, 1e-9);   // nearest rank 1 of 3
  EXPECT_NEAR(h.percentile(0.6), 5.1, 1e-9);   // nearest rank 2 of 3
  EXPECT_NEAR(h.percentile(1.0), 10.1, 1e-9);  // upper edge of the last bin, below the maximum
}

}  // namespace
