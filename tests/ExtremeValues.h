#pragma once
// The extreme values the tests plant in a pass's inputs (the equivalence tests of optimised
// kernels against their scalar references): IEEE specials, the loader's replacement bound
// (|v| > 1e30 is replaced before any pass sees it, docs/errors.md), float max, signed zeros,
// denormals of both signs and a negative. One list, so a value added for one pass is tried on
// every pass; a test adds its own pass's thresholds with extremeValuesAnd.
#include <initializer_list>
#include <limits>
#include <vector>

namespace testvalues {

inline const std::vector<float>& extremeValues() {
    using L = std::numeric_limits<float>;
    static const std::vector<float> values = {
        L::quiet_NaN(), L::infinity(), -L::infinity(),  1e30f,   -1e30f, L::max(), 0.f,
        -0.f,           -1.f,          L::denorm_min(), -3e-39f, 1e-30f};
    return values;
}

/// extremeValues() followed by a test's own edge values (a pass's thresholds: the square of a
/// luminance overflowing, an albedo floor, a motion past the frame).
inline std::vector<float> extremeValuesAnd(std::initializer_list<float> passEdges) {
    std::vector<float> v = extremeValues();
    v.insert(v.end(), passEdges);
    return v;
}

}  // namespace testvalues
