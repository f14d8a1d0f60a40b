#pragma once
// Reads the R, G, B channels of an EXR the CLI wrote, as floats, to check that a file is complete
// (OpenEXR reads every scanline) and to compare runs.
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>

#include <string>
#include <vector>

namespace clitest {

struct RgbImage {
    int width = 0, height = 0;
    std::vector<float> rgb;  ///< planar: R plane, G plane, B plane
};

/// Reads the whole file; false (with `why`) if OpenEXR cannot open it or read every pixel.
inline bool readRgb(const std::string& path, RgbImage& img, std::string* why = nullptr) {
    try {
        Imf::InputFile file(path.c_str());
        const Imath::Box2i dw = file.header().dataWindow();
        img.width = dw.max.x - dw.min.x + 1;
        img.height = dw.max.y - dw.min.y + 1;
        const size_t n = size_t(img.width) * size_t(img.height);
        img.rgb.assign(3 * n, 0.f);
        Imf::FrameBuffer fb;
        const char* names[] = {"R", "G", "B"};
        for (int c = 0; c < 3; ++c) {
            char* base =
                reinterpret_cast<char*>(img.rgb.data() + size_t(c) * n) -
                (ptrdiff_t(dw.min.x) + ptrdiff_t(dw.min.y) * img.width) * ptrdiff_t(sizeof(float));
            fb.insert(names[c], Imf::Slice(Imf::FLOAT, base, sizeof(float),
                                           sizeof(float) * size_t(img.width)));
        }
        file.setFrameBuffer(fb);
        if (!file.isComplete()) {
            if (why) *why = "incomplete file";
            return false;
        }
        file.readPixels(dw.min.y, dw.max.y);
        return true;
    } catch (const std::exception& e) {
        if (why) *why = e.what();
        return false;
    }
}

}  // namespace clitest
