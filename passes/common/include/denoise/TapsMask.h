#pragma once
// The taps mask one Reprojection records (output `taps`) and another takes instead of testing
// again (input `sharedTaps`). Its bits 0-24 are Reprojection's (PixelReprojection-inl.h); this
// value is the contract with a pass in between that moves some pixels' motion (VirtualMotion).
#include <cstdint>

namespace kestrel::taps {

/// A pixel whose motion is not the one its taps were tested with: a Reprojection given a mask
/// with any such pixel runs its own consistency tests for the frame (the same output as the
/// shared tests wherever the motion is the same). Bit 31, which no test sets.
constexpr int32_t kUntested = INT32_MIN;

}  // namespace kestrel::taps
