#include "LoaderDecode.h"

#include <OpenEXR/ImfFrameBuffer.h>

#include <cstdint>

#include "ZipScanlines.h"
#include "kestrel/Log.h"

namespace kestrel::exr {

void readChannels(ExrInput& in, const Box& dp, int W, size_t N,
                  const std::vector<std::pair<std::string, float*>>& chans,
                  const std::vector<float>& fillv, int threads, const Workspace& lent,
                  const std::vector<AbsurdFix>& fixes) {
    const Box dw = in.dataWindow();
    const bool covers = dw.x0 <= dp.x0 && dw.y0 <= dp.y0 && dw.x1 >= dp.x1 && dw.y1 >= dp.y1;
    const bool inside = dw.x0 >= dp.x0 && dw.y0 >= dp.y0 && dw.x1 <= dp.x1 && dw.y1 <= dp.y1;
    if (!covers)
        for (size_t k = 0; k < chans.size(); ++k) fillPlane(chans[k].second, N, fillv[k]);
    const int ix0 = std::max(dw.x0, dp.x0), ix1 = std::min(dw.x1, dp.x1);
    const int iy0 = std::max(dw.y0, dp.y0), iy1 = std::min(dw.y1, dp.y1);
    if (ix0 > ix1 || iy0 > iy1) return;  // no overlap: fill values only
    if (const ZipScanlines* zip = in.zip()) {
        std::string why;
        if (zip->decode(dp, W, chans, fillv, threads, &why, nullptr, lent, fixes)) return;
        spdlog::debug("ExrLoader: {}: {}; reading it through OpenEXR", in.path(), why);
        for (const AbsurdFix& f : fixes)
            if (f.replaced) *f.replaced = 0;  // counted again below
    }
    Imf::FrameBuffer fb;
    std::vector<float> clip;  // only when the data window pokes out of the display
    const size_t dwW = size_t(dw.width()), rows = size_t(iy1 - iy0 + 1);
    if (!inside) clip.resize(dwW * rows * chans.size());
    for (size_t k = 0; k < chans.size(); ++k) {
        // Slice base: the address pixel (0, 0) would have (OpenEXR's convention).
        uintptr_t base;
        size_t yStride;
        if (inside) {
            int64_t origin = int64_t(dp.x0) + int64_t(dp.y0) * W;
            base = uintptr_t(chans[k].second) - uintptr_t(origin * 4);
            yStride = size_t(W) * 4;
        } else {
            float* buf = clip.data() + k * dwW * rows;
            int64_t origin = int64_t(dw.x0) + int64_t(iy0) * int64_t(dwW);
            base = uintptr_t(buf) - uintptr_t(origin * 4);
            yStride = dwW * 4;
        }
        fb.insert(chans[k].first, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(base), 4, yStride,
                                             1, 1, fillv[k]));
    }
    in.file().setFrameBuffer(fb);
    in.file().readPixels(iy0, iy1);
    if (!inside)
        for (size_t k = 0; k < chans.size(); ++k)
            for (int y = iy0; y <= iy1; ++y) {
                const float* src =
                    clip.data() + k * dwW * rows + size_t(y - iy0) * dwW + size_t(ix0 - dw.x0);
                float* dst = chans[k].second + size_t(y - dp.y0) * size_t(W) + size_t(ix0 - dp.x0);
                std::copy(src, src + (ix1 - ix0 + 1), dst);
            }
    // OpenEXR's path (other compressions, damaged files): a pass of its own over the planes.
    for (size_t k = 0; k < fixes.size(); ++k)
        if (fixes[k].on)
            *fixes[k].replaced += replaceAbsurd(chans[k].second, N, fixes[k].fill, fixes[k].lowest);
}

}  // namespace kestrel::exr
