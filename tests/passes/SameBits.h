#pragma once
// Bitwise comparison of a pass's output with its reference's: the equivalence tests' check that
// an optimised kernel computes exactly what the plain scalar reference does.
#include <gtest/gtest.h>
#include <kestrel/Image.h>

#include <cstring>

namespace svgftest {

/// Whether every value of `pass` has the bits of `reference`'s (the sign of zero and NaN payloads
/// included) over its first `channels` channels (all by default); names the first that differs.
inline ::testing::AssertionResult sameBits(const kestrel::Image& pass,
                                           const kestrel::Image& reference, int channels = -1) {
    if (pass.extent() != reference.extent() || pass.format() != reference.format())
        return ::testing::AssertionFailure() << "the images differ in size or format";
    const int n = channels < 0 ? kestrel::channelCount(pass.format()) : channels;
    for (int c = 0; c < n; ++c)
        for (int y = 0; y < pass.height(); ++y)
            for (int x = 0; x < pass.width(); ++x)
                if (std::memcmp(&pass.at(c, x, y), &reference.at(c, x, y), sizeof(float)) != 0)
                    return ::testing::AssertionFailure()
                           << "channel " << c << " pixel (" << x << ", " << y << "): pass "
                           << pass.at(c, x, y) << " reference " << reference.at(c, x, y);
    return ::testing::AssertionSuccess();
}

}  // namespace svgftest
