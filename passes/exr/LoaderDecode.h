#pragma once
// Decoding file channels into the frame's planes (the display window), and the plane helpers
// the loader's steps share.
#include <algorithm>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "Absurd.h"
#include "Box.h"
#include "ExrInput.h"
#include "Workspace.h"
#include "kestrel/Image.h"

namespace kestrel::exr {

inline float* asFloats(const ImageView& v, int c) {
    return v.planes[size_t(c)];
}

inline void fillPlane(float* p, size_t n, float value) {
    std::fill(p, p + n, value);
}

/// Decodes `chans` of `in` into display-window planes (W x H of `dp`) on up to `threads`
/// threads; pixels outside the data window get the channel's fill value. ZIP/ZIPS scan-line
/// files take the fast path (ZipScanlines.h); the rest, and files it finds damaged, are read
/// by OpenEXR. Throws what OpenEXR throws.
void readChannels(ExrInput& in, const Box& dp, int W, size_t N,
                  const std::vector<std::pair<std::string, float*>>& chans,
                  const std::vector<float>& fillv, int threads, const Workspace& lent = {},
                  const std::vector<AbsurdFix>& fixes = {});

}  // namespace kestrel::exr
