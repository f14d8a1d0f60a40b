#pragma once
// Writing small EXR files for the eval tests.
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace kestrel::eval::testutil {

/// A fresh, empty temporary folder named after the running test.
inline std::filesystem::path tempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::filesystem::path d =
        std::filesystem::temp_directory_path() /
        (std::string("kestrel_eval_") + info->test_suite_name() + "_" + info->name());
    std::filesystem::remove_all(d);
    std::filesystem::create_directories(d);
    return d;
}

/// Writes a w x h EXR with the channels in the order given; channel i at (x, y) holds
/// value(i, x, y).
inline void writeExr(const std::filesystem::path& path, int w, int h,
                     const std::vector<std::string>& names,
                     const std::function<float(int, int, int)>& value,
                     Imf::PixelType type = Imf::FLOAT) {
    Imf::Header header(w, h);
    for (const auto& n : names) header.channels().insert(n, Imf::Channel(type));
    std::vector<std::vector<float>> planes(names.size(), std::vector<float>(size_t(w) * h));
    std::vector<std::vector<half>> halves(names.size(), std::vector<half>(size_t(w) * h));
    Imf::FrameBuffer fb;
    for (size_t i = 0; i < names.size(); ++i) {
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const float v = value(int(i), x, y);
                planes[i][size_t(y) * w + x] = v;
                halves[i][size_t(y) * w + x] = half(v);
            }
        if (type == Imf::HALF)
            fb.insert(names[i], Imf::Slice(Imf::HALF, (char*)halves[i].data(), sizeof(half),
                                           sizeof(half) * w));
        else
            fb.insert(names[i], Imf::Slice(Imf::FLOAT, (char*)planes[i].data(), sizeof(float),
                                           sizeof(float) * w));
    }
    Imf::OutputFile file(path.c_str(), header);
    file.setFrameBuffer(fb);
    file.writePixels(h);
}

}  // namespace kestrel::eval::testutil
