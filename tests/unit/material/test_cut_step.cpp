// The hosts' one sub-stepping policy (talus/material/cut_step.hpp) against
// its definition: n = max(2, ceil(1 / f)) parts, f floored at 1e-3, none
// once a part would fall below 1e-6 of the original increment.
#include <talus/material/cut_step.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

using talus::cut_step::parts;

TEST(CutStep, SplitsIntoTheCeilingOfTheInverseFactor) {
    EXPECT_EQ(parts(0.5, 1.0), 2);
    EXPECT_EQ(parts(0.25, 1.0), 4); // 1/f exact: no extra part from rounding
    EXPECT_EQ(parts(0.3, 1.0), 4);  // ceil(3.33)
    EXPECT_EQ(parts(0.1, 1.0), 10);
}

TEST(CutStep, AtLeastHalvesAndAtMostAThousandParts) {
    EXPECT_EQ(parts(0.9, 1.0), 2); // a factor near 1 still halves
    EXPECT_EQ(parts(1e-9, 1.0), 1000);
    // A factor that is not a number is treated as a plain halving.
    EXPECT_EQ(parts(std::numeric_limits<double>::quiet_NaN(), 1.0), 2);
}

TEST(CutStep, StopsBelowAMillionthOfTheIncrement) {
    // Halving from 1: 2^-19 = 1.9e-6 is the last allowed part, 2^-20 = 9.5e-7
    // is not.
    EXPECT_EQ(parts(0.5, std::ldexp(1.0, -18)), 2);
    EXPECT_EQ(parts(0.5, std::ldexp(1.0, -19)), 0);
    // A part of exactly 1e-6 is allowed (1e-3 split in 1000).
    EXPECT_EQ(parts(1e-3, 1e-3), 1000);
    EXPECT_EQ(parts(1e-3, 0.999e-3), 0);
}
