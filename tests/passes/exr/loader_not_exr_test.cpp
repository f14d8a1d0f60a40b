// Frames that are images of another format (PNG, Radiance HDR, TIFF, JPEG): the loader refuses
// the first one naming the file and its format, and says what is needed instead (OpenEXR with
// depth, normals and motion beside the colour), instead of "bad magic number".
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "ExrLoader.h"
#include "exr_test_util.h"
#include "kestrel/testing/PassHarness.h"

using kestrel::exr::ExrLoader;
using kestrel::testing::PassHarness;
using namespace exrtest;

namespace {

/// The error resolving a loader over `name` (a file holding `bytes`), "" when there is none.
std::string refusal(const TempDir& tmp, const std::string& name, const std::string& bytes) {
    std::ofstream(tmp.path / name, std::ios::binary) << bytes;
    std::string pattern = name;
    pattern.replace(pattern.find("0001"), 4, "####");
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / pattern).string()}});
    return resolveError(h.pass());
}

}  // namespace

TEST(ExrLoaderNotExr, ImageFramesOfAnotherFormatAreNamedWithWhatIsNeeded) {
    TempDir tmp("not-exr");
    const std::string tail(64, '\0');  // a body after the signature
    const struct {
        const char* file;
        std::string bytes;
        const char* format;
    } cases[] = {
        {"frame_0001.png", std::string("\x89PNG\r\n\x1a\n", 8) + tail, "a PNG image"},
        {"frame_0001.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n" + tail, "a Radiance HDR image"},
        {"frame_0001.tif", std::string("II*\0", 4) + tail, "a TIFF image"},
        {"frame_0001.jpg", std::string("\xff\xd8\xff\xe0", 4) + tail, "a JPEG image"},
    };
    for (const auto& c : cases) {
        const std::string msg = refusal(tmp, c.file, c.bytes);
        EXPECT_NE(msg.find(c.file), std::string::npos) << msg;
        EXPECT_NE(msg.find(c.format), std::string::npos) << msg;
        EXPECT_NE(msg.find("carries colour only"), std::string::npos) << msg;
        EXPECT_NE(msg.find("OpenEXR MultiLayer with the Depth, Normal and Vector passes"),
                  std::string::npos)
            << msg;
    }
    // Anything else is still just not OpenEXR.
    const std::string msg = refusal(tmp, "other_0001.exr", "this is not an image at all");
    EXPECT_NE(msg.find("not an OpenEXR file (bad magic number)"), std::string::npos) << msg;
    EXPECT_EQ(msg.find("carries colour only"), std::string::npos) << msg;
}
