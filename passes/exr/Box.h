#pragma once
#include <cstdint>

namespace kestrel::exr {

/// An EXR window: inclusive bounds, as the file stores them.
struct Box {
    int x0 = 0, y0 = 0, x1 = -1, y1 = -1;
    int64_t width() const { return int64_t(x1) - x0 + 1; }
    int64_t height() const { return int64_t(y1) - y0 + 1; }
    bool operator==(const Box&) const = default;
};

}  // namespace kestrel::exr
