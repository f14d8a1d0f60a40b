// Values beyond the half-float range at write time (docs/design.md section 8): the ExrWriter
// plugin, run in a graph, must clamp to +-65504 (half) and never store Inf or NaN in the file.
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>

#include "Checks.h"

namespace stability {
namespace {

namespace fs = std::filesystem;

constexpr float kInf = std::numeric_limits<float>::infinity();
// 65520 is the smallest float that rounds to half +Inf: a writer that converts before clamping
// writes Inf there.
const float kValues[] = {1e6f,    -1e6f,   65504.f,
                         65519.f, 65520.f, 7e4f,
                         kInf,    -kInf,   std::numeric_limits<float>::quiet_NaN(),
                         1e-10f,  0.5f,    3e38f};
constexpr int kCount = int(sizeof(kValues) / sizeof(kValues[0]));

std::vector<float> readChannel(const fs::path& file, const char* name, int& w, int& h) {
    Imf::InputFile in(file.c_str());
    const Imath::Box2i dw = in.header().dataWindow();
    w = dw.max.x - dw.min.x + 1;
    h = dw.max.y - dw.min.y + 1;
    std::vector<float> px(size_t(w) * size_t(h));
    Imf::FrameBuffer fb;
    fb.insert(name,
              Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(px.data() - dw.min.x - dw.min.y * w),
                         sizeof(float), sizeof(float) * size_t(w)));
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    return px;
}

void writeAndCheck(const std::string& pixelType, float limit) {
    const fs::path dir = fs::temp_directory_path() / ("kestrel-stability-writer-" + pixelType);
    fs::remove_all(dir);
    fs::create_directories(dir);
    setScenario("writer", plainScene({kCount, 3}, [](int64_t, Frame& f) {
                    for (int x = 0; x < kCount; ++x)
                        for (int c = 0; c < 3; ++c) f["color"].at(c, x, 1) = kValues[x];
                }));
    const std::string json = R"({"kestrel": 1, "name": "writer", "passes": [
        {"name": "input", "type": "StabilitySource", "params": {"scenario": "writer"}},
        {"name": "output", "type": "ExrWriter", "params": {"path": ")" +
                             (dir / "frame.####.exr").string() + R"(", "pixelType": ")" +
                             pixelType + R"("}}],
        "edges": [{"from": "input.color", "to": "output.color"}]})";
    TestGraph g{kestrel::parseGraph(json), "input.color"};
    g.desc.outputs.push_back(g.output);
    RunOptions options;
    options.frames = 1;
    run(g, options);
    const fs::path file = dir / "frame.0001.exr";
    ASSERT_TRUE(fs::exists(file));
    for (const char* ch : {"R", "G", "B"}) {
        int w = 0, h = 0;
        const std::vector<float> px = readChannel(file, ch, w, h);
        ASSERT_EQ(w, kCount);
        ASSERT_EQ(h, 3);
        for (int x = 0; x < kCount; ++x) {
            const float v = px[size_t(w + x)], in = kValues[x];
            ASSERT_TRUE(std::isfinite(v)) << ch << " input " << in << " stored as " << v;
            EXPECT_LE(std::fabs(v), limit) << ch << " input " << in;
            if (std::isnan(in)) {
                EXPECT_EQ(v, 0.f) << "NaN is written as 0";
            }
            if (std::isinf(in) || std::fabs(in) >= limit) {
                EXPECT_EQ(std::fabs(v), limit) << ch << " input " << in << " clamps to the limit";
            }
        }
    }
    fs::remove_all(dir);
}

TEST(WriterRange, HalfClampsTo65504AndStoresNoInfOrNaN) {
    writeAndCheck("half", 65504.f);
}

TEST(WriterRange, FloatStoresNoInfOrNaN) {
    writeAndCheck("float", std::numeric_limits<float>::max());
}

}  // namespace
}  // namespace stability
