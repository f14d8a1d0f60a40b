// ExrWriter previews through OpenColorIO: with $OCIO naming a config, the PNG preview is the
// config's default display and view of the scene-linear image (a tiny config written here);
// without it, the built-in tone curve and sRGB; a config that does not load is refused naming
// $OCIO.
#include <gtest/gtest.h>
#include <png.h>

#include <cstdlib>
#include <fstream>

#include "ExrWriter.h"
#include "exr_test_util.h"
#include "kestrel/testing/PassHarness.h"

using kestrel::Format;
using kestrel::Image;
using kestrel::exr::ExrWriter;
using kestrel::testing::PassHarness;
using namespace exrtest;

namespace {

/// A config whose one display and view halves scene-linear values (no curve, no sRGB), so the
/// expected preview is exact.
const char* kHalvingConfig = R"(ocio_profile_version: 2

roles:
  default: linear
  scene_linear: linear

file_rules:
  - !<Rule> {name: Default, colorspace: default}

displays:
  half:
    - !<View> {name: scaled, colorspace: halved}

active_displays: [half]
active_views: [scaled]

colorspaces:
  - !<ColorSpace>
    name: linear
    isdata: false

  - !<ColorSpace>
    name: halved
    isdata: false
    from_scene_reference: !<MatrixTransform> {matrix: [0.5, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 1]}
)";

/// Sets $OCIO for the test's duration.
struct ScopedOcio {
    explicit ScopedOcio(const std::string& value) { ::setenv("OCIO", value.c_str(), 1); }
    ~ScopedOcio() { ::unsetenv("OCIO"); }
};

/// The first pixel of an RGB8 PNG.
std::vector<int> firstPixel(const fs::path& file) {
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&image, file.c_str())) return {};
    image.format = PNG_FORMAT_RGB;
    std::vector<png_byte> buf(PNG_IMAGE_SIZE(image));
    if (!png_image_finish_read(&image, nullptr, buf.data(), 0, nullptr)) return {};
    return {buf[0], buf[1], buf[2]};
}

std::vector<int> previewOf(const fs::path& dir, float value) {
    Image img(4, 2, Format::Float3);
    img.fill(value);
    auto h = PassHarness::make<ExrWriter>({4, 2}, {{"path", (dir / "out.####.exr").string()},
                                                   {"preview", (dir / "prev.####.png").string()}});
    kestrel::RunContext rc;
    rc.firstFrame = 1;
    h.pass().beginRun(rc);
    h.bind("color", img);
    h.ctx.frameNumber = 1;
    h.run();
    return firstPixel(dir / "prev.0001.png");
}

}  // namespace

TEST(ExrWriterOcio, PreviewUsesTheConfigsDefaultDisplayAndView) {
    TempDir tmp("wocio");
    { std::ofstream(tmp.path / "config.ocio") << kHalvingConfig; }
    const auto builtIn = previewOf(tmp.path, 0.6f);
    ASSERT_EQ(builtIn.size(), 3u);
    ScopedOcio env((tmp.path / "config.ocio").string());
    if (!kestrel::exr::OcioView::fromEnvironment()) {
#ifdef KESTREL_HAS_OCIO_MODULE  // built: its module must be found and opened on demand
        FAIL() << "the OpenColorIO module (kestrel_ocio.so) was built but did not open";
#endif
        GTEST_SKIP() << "built without OpenColorIO";
    }
    const auto viaOcio = previewOf(tmp.path, 0.6f);
    EXPECT_EQ(viaOcio, (std::vector<int>{77, 77, 77}));  // 0.6 halved: 0.3 * 255 = 76.5
    EXPECT_NE(viaOcio, builtIn);
}

TEST(ExrWriterOcio, ConfigThatDoesNotLoadIsRefusedNamingOcio) {
    TempDir tmp("wociobad");
    { std::ofstream(tmp.path / "broken.ocio") << "ocio_profile_version: 2\nroles: [\n"; }
    ScopedOcio env((tmp.path / "broken.ocio").string());
    try {
        const auto view = kestrel::exr::OcioView::fromEnvironment();
        if (!view) GTEST_SKIP() << "built without OpenColorIO";
        FAIL() << "no error";
    } catch (const kestrel::Error& e) {
        EXPECT_NE(std::string(e.what()).find("$OCIO=" + (tmp.path / "broken.ocio").string()),
                  std::string::npos)
            << e.what();
    }
}
