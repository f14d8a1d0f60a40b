// A render set up the usual way for denoising (Combined + "Denoising Data", without DiffCol,
// Normal or Z): the loader reads Cycles' denoiser features in place of the missing G-buffer
// passes, in Kestrel's conventions (data/README.md: Denoising Normal in camera space, Denoising
// Depth a ray-path length with 0 on the background).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <vector>

#include "ExrLoader.h"
#include "exr_test_util.h"
#include "kestrel/Conventions.h"
#include "kestrel/testing/PassHarness.h"

using kestrel::exr::ExrLoader;
using kestrel::testing::PassHarness;
using namespace exrtest;

namespace {

Imath::Box2i box2(int w, int h) {
    return Imath::Box2i({0, 0}, {w - 1, h - 1});
}

/// A 2x1 Blender frame of `ch` (Combined added) written to `tmp` with no camera.json, and a
/// loader on it.
PassHarness loaderOn(const TempDir& tmp, Channels ch);

void addGroup(Channels& ch, const std::string& layer, const char* comps, std::vector<float> v) {
    for (int c = 0; comps[c]; ++c)
        ch["ViewLayer." + layer + "." + comps[c]].assign(2, v[size_t(c)]);
}

PassHarness loaderOn(const TempDir& tmp, Channels ch) {
    addGroup(ch, "Combined", "RGBA", {0.5f, 0.5f, 0.5f, 1.f});
    writeExr(tmp.path / "f.0001.exr", box2(2, 1), ch);
    return PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "f.####.exr").string()}});
}

/// Frame 5 of blender-street re-written with only `passes` (each "Pass.comps", e.g.
/// "Combined.RGBA") beside its camera.json, then loaded for `output`.
PassHarness loadStreetSubset(const std::string& dir, const TempDir& tmp,
                             const std::vector<std::string>& passes, const std::string& output,
                             bool withCamera = true) {
    const std::string file = dir + "/noisy/frame_0005.exr";
    Channels ch;
    for (const auto& p : passes) {
        const auto dot = p.find('.');
        for (char c : p.substr(dot + 1)) {
            const std::string name = "ViewLayer." + p.substr(0, dot) + "." + c;
            ch[name] = readChannel(file, name);
        }
    }
    writeExr(tmp.path / "frame_0005.exr", box2(320, 180), ch);
    if (withCamera) std::filesystem::copy_file(dir + "/camera.json", tmp.path / "camera.json");
    auto h =
        PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "frame_####.exr").string()}});
    h.useOutputs({output});
    h.ctx.frameNumber = 5;
    h.run();
    return h;
}

}  // namespace

TEST(ExrLoaderDenoisingData, FeaturesStandInForMissingPasses) {
    TempDir tmp("denoising-data");
    Channels ch;
    addGroup(ch, "Denoising Albedo", "RGB", {0.25f, 0.5f, 0.75f});
    addGroup(ch, "Denoising Normal", "XYZ", {0.f, 1.f, 0.f});
    ch["ViewLayer.Denoising Depth.Z"] = {7.5f, 0.f};  // pixel 1 is background
    auto h = loaderOn(tmp, ch);
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    EXPECT_EQ(rc.absent.count("albedo"), 0u);
    EXPECT_EQ(rc.absent.count("normal"), 0u);
    EXPECT_EQ(rc.absent.count("depth"), 0u);
    EXPECT_EQ(rc.absent.count("diffuseAlbedo"), 1u);  // the split needs DiffCol/GlossCol
    h.useOutputs({"albedo", "normal", "depth"});
    h.ctx.frameNumber = 1;
    h.run();
    EXPECT_EQ(h.out("albedo").at(2, 0, 0), 0.75f);
    EXPECT_EQ(h.out("normal").at(1, 1, 0), 1.f);  // no camera.json: stays in camera space
    EXPECT_EQ(h.out("depth").at(0, 0, 0), 7.5f);
    EXPECT_EQ(h.out("depth").at(0, 1, 0), kestrel::kBackgroundDepth);
}

TEST(ExrLoaderDenoisingData, MissingNormalIsNamedAsBlendersUiNamesIt) {
    TempDir tmp("no-normal");
    Channels ch;
    auto h = loaderOn(tmp, ch);
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    EXPECT_EQ(rc.absent["normal"],
              "layout blender has no channel ViewLayer.Normal.R/G/B (nor ViewLayer.Denoising "
              "Normal): enable View Layer > Passes > Data > Normal");
    EXPECT_NE(rc.absent["albedo"].find("Light > Diffuse > Color"), std::string::npos);
    EXPECT_NE(rc.absent["position"].find("enable View Layer > Passes > Data > Position"),
              std::string::npos);
    EXPECT_NE(rc.absent["motion"].find("enable View Layer > Passes > Data > Vector"),
              std::string::npos);
    EXPECT_NE(rc.absent["objectId"].find("Data > Indexes > Object Index"), std::string::npos);
}

// With a camera, the camera-space Denoising Normal is rotated to world space: on the real
// outdoor render (which has both) it then agrees with the Normal pass on the surfaces it
// describes (not through mirrors: there it describes the reflected surface).
TEST(ExrLoaderDenoisingData, DenoisingNormalRotatedToWorldMatchesNormalPass) {
    const std::string dir = sharedData("blender-street");
    if (dir.empty() || !std::filesystem::exists(dir + "/noisy/frame_0005.exr"))
        GTEST_SKIP() << "../shared/data/blender-street not present";
    const std::string file = dir + "/noisy/frame_0005.exr";
    TempDir tmp("street-nonormal");
    auto h = loadStreetSubset(dir, tmp, {"Combined.RGBA", "Denoising Normal.XYZ"}, "normal");
    const int w = 320, hgt = 180;
    const std::vector<float> nx = readChannel(file, "ViewLayer.Normal.X"),
                             ny = readChannel(file, "ViewLayer.Normal.Y"),
                             nz = readChannel(file, "ViewLayer.Normal.Z");
    int agree = 0, surface = 0;
    for (int y = 0; y < hgt; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * w + size_t(x);
            const auto& n = h.out("normal");
            const float d = n.at(0, x, y) * nx[i] + n.at(1, x, y) * ny[i] + n.at(2, x, y) * nz[i];
            if (nx[i] * nx[i] + ny[i] * ny[i] + nz[i] * nz[i] < 0.5f) continue;  // background
            ++surface;
            agree += d > 0.99f;
        }
    ASSERT_GT(surface, w * hgt / 3);
    EXPECT_GT(agree, surface * 8 / 10) << agree << " of " << surface;
}

namespace {

/// Frame 5 of blender-street with Combined and one depth pass only (no Position, Vector or
/// normal pass) beside its camera.json, loaded for `output`: the fraction of the surface pixels
/// of the pass `truth` (XYZ; (0, 0, 0) on the background) where agrees(loaded, true value,
/// camera-to-world) holds.
template <class Agrees>
double agreement(const std::string& dir, const std::string& depthPass, const std::string& output,
                 const std::string& truth, Agrees agrees) {
    const std::string file = dir + "/noisy/frame_0005.exr";
    TempDir tmp("street-" + output + "-from-" + depthPass);
    auto h = loadStreetSubset(dir, tmp, {"Combined.RGBA", depthPass + ".Z"}, output);
    const int w = 320, hgt = 180;
    EXPECT_TRUE(h.scene.hasCamera);
    const auto cameraToWorld = kestrel::inverse(h.scene.worldToCamera);
    EXPECT_TRUE(cameraToWorld.has_value());
    std::vector<float> t[3];
    for (int c = 0; c < 3; ++c) t[c] = readChannel(file, "ViewLayer." + truth + "." + "XYZ"[c]);
    int agree = 0, surface = 0;
    for (int y = 0; y < hgt; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * w + size_t(x);
            const double v[3] = {h.out(output).at(0, x, y), h.out(output).at(1, x, y),
                                 h.out(output).at(2, x, y)},
                         tv[3] = {t[0][i], t[1][i], t[2][i]};
            if (tv[0] == 0 && tv[1] == 0 && tv[2] == 0) continue;  // background
            ++surface;
            agree += agrees(v, tv, *cameraToWorld);
        }
    EXPECT_GT(surface, w * hgt / 3);
    return double(agree) / double(std::max(surface, 1));
}

/// The fraction of surface pixels whose position lies within `tolerance` times the camera
/// distance of the Position pass's.
double positionAgreement(const std::string& dir, const std::string& depthPass, double tolerance) {
    return agreement(dir, depthPass, "position", "Position",
                     [&](const double* p, const double* t, const kestrel::Mat4& cameraToWorld) {
                         double err2 = 0, dist2 = 0;
                         for (int c = 0; c < 3; ++c) {
                             const double eye = cameraToWorld.m[c][3];
                             err2 += (p[c] - t[c]) * (p[c] - t[c]);
                             dist2 += (t[c] - eye) * (t[c] - eye);
                         }
                         return err2 < tolerance * tolerance * dist2;
                     });
}

/// The fraction of surface pixels whose normal is within `degrees` of the Normal pass's.
double normalAgreement(const std::string& dir, const std::string& depthPass, double degrees) {
    const double cosTol = std::cos(degrees * M_PI / 180.0);
    return agreement(dir, depthPass, "normal", "Normal",
                     [&](const double* n, const double* t, const kestrel::Mat4&) {
                         return n[0] * t[0] + n[1] * t[1] + n[2] * t[2] > cosTol;
                     });
}

}  // namespace

// A render without Position (and without Vector): the loader unprojects the depth it has with
// camera.json, so Reprojection can use its matrix path instead of the identity. Planar Z
// matches the Position pass everywhere (0.1% of the distance); Denoising Depth is a ray length
// that runs 0.5-1% short of the Position pass's distance (ratio 0.990 / 0.993 / 0.995 at the
// 10th / 50th / 90th percentile on this frame) and looks through near-specular surfaces, so it
// matches within 2% on most of the frame.
TEST(ExrLoaderDenoisingData, PositionUnprojectedFromDepthMatchesThePositionPass) {
    const std::string dir = sharedData("blender-street");
    if (dir.empty() || !std::filesystem::exists(dir + "/noisy/frame_0005.exr"))
        GTEST_SKIP() << "../shared/data/blender-street not present";
    const double planar = positionAgreement(dir, "Depth", 1e-3),
                 rayLength = positionAgreement(dir, "Denoising Depth", 0.02);
    std::printf(
        "[ measured ] positions matched: from Z %.4f (0.1%%), from Denoising Depth %.4f "
        "(2%%)\n",
        planar, rayLength);
    EXPECT_GT(planar, 0.99);
    EXPECT_GT(rayLength, 0.85);
}

// A render with neither Normal nor Denoising Normal (Combined and a depth pass): the loader
// reconstructs geometric normals from the depth and camera.json, so SVGF's normal term still
// stops its filters at creases. They match the shading normals of the Normal pass on most of
// the frame (96% within 10 degrees from Z, 93% from Denoising Depth); not on smooth-shaded curved
// objects (a geometric normal is the facet's), along depth edges, or where Denoising Depth looks
// through glass and mirrors.
TEST(ExrLoaderDenoisingData, NormalReconstructedFromDepthMatchesTheNormalPass) {
    const std::string dir = sharedData("blender-street");
    if (dir.empty() || !std::filesystem::exists(dir + "/noisy/frame_0005.exr"))
        GTEST_SKIP() << "../shared/data/blender-street not present";
    const double planar = normalAgreement(dir, "Depth", 10.0),
                 rayLength = normalAgreement(dir, "Denoising Depth", 10.0);
    std::printf("[ measured ] normals within 10 degrees: from Z %.4f, from Denoising Depth %.4f\n",
                planar, rayLength);
    EXPECT_GT(planar, 0.94);     // measured 0.9647
    EXPECT_GT(rayLength, 0.90);  // measured 0.9281
}

// Without a camera (Combined and Z only, no camera.json) the normals are reconstructed in
// camera space from an assumed field of view (Blender's default lens), where they were left out
// before and svgf.json refused the render. Against the Normal pass turned to camera space with
// the real camera: a wrong focal length leans them (blender-street's lens is not the default),
// but a plane keeps one normal, which is what the filters' normal test between pixels needs.
TEST(ExrLoaderDenoisingData, NormalReconstructedFromDepthWithoutACamera) {
    const std::string dir = sharedData("blender-street");
    if (dir.empty() || !std::filesystem::exists(dir + "/noisy/frame_0005.exr"))
        GTEST_SKIP() << "../shared/data/blender-street not present";
    const std::string file = dir + "/noisy/frame_0005.exr";
    TempDir tmp("street-normal-no-camera"), cam("street-camera");
    auto h = loadStreetSubset(dir, tmp, {"Combined.RGBA", "Depth.Z"}, "normal", false);
    EXPECT_FALSE(h.scene.hasCamera);
    const auto withCamera = loadStreetSubset(dir, cam, {"Combined.RGBA", "Depth.Z"}, "depth");
    const auto& R = withCamera.scene.worldToCamera.m;
    std::vector<float> t[3];
    for (int c = 0; c < 3; ++c)
        t[c] = readChannel(file, std::string("ViewLayer.Normal.") + "XYZ"[c]);
    int within15 = 0, unit = 0, surface = 0;
    for (int y = 0; y < 180; ++y)
        for (int x = 0; x < 320; ++x) {
            const size_t i = size_t(y) * 320 + size_t(x);
            if (t[0][i] == 0 && t[1][i] == 0 && t[2][i] == 0) continue;  // background
            ++surface;
            double dot = 0, len2 = 0;
            for (int r = 0; r < 3; ++r) {
                const double n = h.out("normal").at(r, x, y);
                const double truth = R[r][0] * t[0][i] + R[r][1] * t[1][i] + R[r][2] * t[2][i];
                dot += n * truth;
                len2 += n * n;
            }
            unit += std::fabs(len2 - 1.0) < 1e-3;
            within15 += dot > std::cos(15.0 * M_PI / 180.0);
        }
    ASSERT_GT(surface, 320 * 180 / 3);
    std::printf("[ measured ] without a camera: unit normals %.4f, within 15 degrees %.4f\n",
                double(unit) / surface, double(within15) / surface);
    EXPECT_GT(unit, surface * 99 / 100);
    EXPECT_GT(within15, surface * 8 / 10);
}

// The same on generated data: a plane seen by a 60 degree camera, loaded without one (the loader
// assumes 39.6 degrees) still gets one unit normal over the whole plane, facing the camera and
// leaning as the assumed lens predicts.
TEST(ExrLoaderDenoisingData, PlaneKeepsOneNormalUnderAnAssumedCamera) {
    TempDir tmp("plane-no-camera");
    const int w = 16, h = 12;
    const double tanX = std::tan(30.0 * M_PI / 180.0), tanY = tanX * h / w;
    Channels ch;
    for (const char* c : {"R", "G", "B", "A"})
        ch[std::string("ViewLayer.Combined.") + c].assign(size_t(w * h), 0.5f);
    std::vector<float>& z = ch["ViewLayer.Depth.Z"];
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            // The plane 0.3 x + 0.2 y + z = 4 in camera space (z forward): along the pixel's ray
            // (cx, cy, 1) it lies at planar depth 4 / (0.3 cx + 0.2 cy + 1).
            const double cx = ((x + 0.5) / w * 2 - 1) * tanX, cy = (1 - (y + 0.5) / h * 2) * tanY;
            z.push_back(float(4.0 / (0.3 * cx + 0.2 * cy + 1.0)));
        }
    writeExr(tmp.path / "f.0001.exr", box2(w, h), ch);
    auto l = PassHarness::make<ExrLoader>({1, 1}, {{"path", (tmp.path / "f.####.exr").string()}});
    l.useOutputs({"normal"});
    l.ctx.frameNumber = 1;
    l.run();
    const auto& n = l.out("normal");
    for (int y = 1; y < h - 1; ++y)
        for (int x = 1; x < w - 1; ++x)
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(n.at(c, x, y), n.at(c, w / 2, h / 2), 1e-4) << x << "," << y;
    const float len2 = n.at(0, w / 2, h / 2) * n.at(0, w / 2, h / 2) +
                       n.at(1, w / 2, h / 2) * n.at(1, w / 2, h / 2) +
                       n.at(2, w / 2, h / 2) * n.at(2, w / 2, h / 2);
    EXPECT_NEAR(len2, 1.f, 1e-4f);
    // The assumed camera scales x and y by s = tan(19.8 deg) / tan(30 deg): the plane's normal
    // is then (-0.3 / s, -0.2 / s, 1) normalised, facing the camera (OpenGL camera space: x
    // right, y up, z towards the viewer).
    const double s = std::tan(kestrel::exr::kAssumedFieldOfView * 0.5 * M_PI / 180.0) / tanX;
    const double e[3] = {-0.3 / s, -0.2 / s, 1.0}, len = std::sqrt(e[0] * e[0] + e[1] * e[1] + 1.0);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(n.at(c, w / 2, h / 2), e[c] / len, 1e-3) << c;
}

// With both normal passes, Cycles' Denoising Normal wins: it passes through mirrors and glass
// to the surface they show (blender-street 31.62 -> 34.59 dB with svgf.json). With camera.json
// it is turned to world space; without one it stays in camera space.
TEST(ExrLoaderDenoisingData, DenoisingNormalPreferredToTheNormalPass) {
    const std::string dir = sharedData("blender-street");
    if (dir.empty() || !std::filesystem::exists(dir + "/noisy/frame_0005.exr"))
        GTEST_SKIP() << "../shared/data/blender-street not present";
    TempDir both("street-both-normals"), only("street-denoising-normal");
    auto h = loadStreetSubset(dir, both, {"Combined.RGBA", "Normal.XYZ", "Denoising Normal.XYZ"},
                              "normal");
    auto d = loadStreetSubset(dir, only, {"Combined.RGBA", "Denoising Normal.XYZ"}, "normal");
    // The Denoising Normal wherever it is set; where it is zero (glass and the mirror sphere
    // showing the sky) a unit normal from the Normal pass (ZeroDenoisingNormalFallsBack...).
    int same = 0, set = 0, filled = 0;
    for (int y = 0; y < 180; ++y)
        for (int x = 0; x < 320; ++x) {
            auto at = [&](PassHarness& p, int c) { return p.out("normal").at(c, x, y); };
            if (at(d, 0) != 0.f || at(d, 1) != 0.f || at(d, 2) != 0.f) {
                ++set;
                for (int c = 0; c < 3; ++c) same += at(h, c) == at(d, c);
            } else {
                const float len2 = at(h, 0) * at(h, 0) + at(h, 1) * at(h, 1) + at(h, 2) * at(h, 2);
                filled += std::fabs(len2 - 1.f) < 1e-2f;
            }
        }
    EXPECT_EQ(same, 3 * set);
    EXPECT_GT(filled, 1000);  // 2,018 surface pixels of frame 8 have no Denoising Normal
}

TEST(ExrLoaderDenoisingData, DenoisingNormalStaysInCameraSpaceWithoutACamera) {
    TempDir tmp("both-normals-no-camera");
    Channels ch;
    addGroup(ch, "Normal", "XYZ", {1.f, 0.f, 0.f});
    addGroup(ch, "Denoising Normal", "XYZ", {0.f, 1.f, 0.f});
    auto h = loaderOn(tmp, ch);
    h.useOutputs({"normal"});
    h.ctx.frameNumber = 1;
    h.run();
    EXPECT_EQ(h.out("normal").at(0, 0, 0), 0.f);
    EXPECT_EQ(h.out("normal").at(1, 0, 0), 1.f);
}

// lightThroughMirror: 1 where Denoising Normal is zero on a surface (the path reached a light
// or the sky through a mirror), 0 on the background and where it names a surface; no camera
// needed (KeepExact keeps such a view's 1-spp colour).
TEST(ExrLoaderDenoisingData, LightThroughMirrorWhereDenoisingNormalIsZeroOnASurface) {
    // 0: zero (a light through a mirror); 1: names a surface; 2: damaged (NaN), not a light.
    for (int kind : {0, 1, 2}) {
        const bool namesSurface = kind != 0;
        TempDir tmp("light-mirror-" + std::to_string(kind));
        Channels ch;
        ch["ViewLayer.Normal.X"] = {0.f, 0.f};
        ch["ViewLayer.Normal.Y"] = {1.f, 0.f};  // pixel 1 is background
        ch["ViewLayer.Normal.Z"] = {0.f, 0.f};
        const float dn = kind == 0 ? 0.f : kind == 1 ? 0.6f : std::nanf("");
        addGroup(ch, "Denoising Normal", "XYZ", {dn, 0.f, 0.f});
        auto h = loaderOn(tmp, ch);
        h.useOutputs({"lightThroughMirror"});
        h.ctx.frameNumber = 1;
        h.run();
        EXPECT_EQ(h.out("lightThroughMirror").at(0, 0, 0), namesSurface ? 0.f : 1.f);
        EXPECT_EQ(h.out("lightThroughMirror").at(0, 1, 0), 0.f);
    }
}

// Blender writes 0 motion on the background even when the camera turns; without camera.json
// the turn is unknown, so the loader marks the background's motion unknown (NaN), which
// Reprojection rejects: a sky held still while the camera pans was smeared (the background of
// blender-street-defaults without camera.json: 47.5 dB at 1 spp, 44.4 after svgf.json; now
// 47.5). Surfaces keep their motion vectors.
TEST(ExrLoaderDenoisingData, BackgroundMotionIsUnknownWithoutACamera) {
    TempDir tmp("sky-no-camera");
    Channels ch;
    addGroup(ch, "Vector", "XYZW", {0.25f, 0.5f, 0.f, 0.f});
    ch["ViewLayer.Depth.Z"] = {5.f, 1e10f};  // pixel 1 is background
    auto h = loaderOn(tmp, ch);
    h.useOutputs({"motion"});
    h.ctx.frameNumber = 1;
    h.run();
    EXPECT_EQ(h.out("motion").at(0, 0, 0), 0.25f);
    EXPECT_EQ(h.out("motion").at(1, 0, 0), -0.5f);  // Blender's y points up the image
    EXPECT_TRUE(std::isnan(h.out("motion").at(0, 1, 0)));
    EXPECT_TRUE(std::isnan(h.out("motion").at(1, 1, 0)));
}

// Cycles' Denoising Normal is zero where the path passed a mirror to the sky or a light: on a
// point-sampled render the loader gives such a surface pixel the Normal pass's normal reversed
// (the filters then join it with the rest of what the mirror shows, never with the mirror's
// frame); on an anti-aliased one the zero stays (ExrLoader::planAntiAliasing says why).
TEST(ExrLoaderDenoisingData, ZeroDenoisingNormalFallsBackToTheReversedNormalPass) {
    for (const char* aa : {"false", "true"}) {
        TempDir tmp(std::string("zero-normal-") + aa);
        Channels ch;
        ch["ViewLayer.Denoising Normal.X"] = {0.f, 0.f};
        ch["ViewLayer.Denoising Normal.Y"] = {1.f, 0.f};  // pixel 1: zero
        ch["ViewLayer.Denoising Normal.Z"] = {0.f, 0.f};
        addGroup(ch, "Normal", "XYZ", {0.f, 0.f, 1.f});
        ch["ViewLayer.Depth.Z"] = {5.f, 5.f};
        addGroup(ch, "Combined", "RGBA", {0.5f, 0.5f, 0.5f, 1.f});
        writeExr(tmp.path / "f.0001.exr", box2(2, 1), ch);
        auto h = PassHarness::make<ExrLoader>(
            {1, 1}, {{"path", (tmp.path / "f.####.exr").string()}, {"antiAliased", aa}});
        h.useOutputs({"normal"});
        h.ctx.frameNumber = 1;
        h.run();
        SCOPED_TRACE(std::string("antiAliased ") + aa);
        EXPECT_EQ(h.out("normal").at(1, 0, 0), 1.f);  // Denoising Normal where it is set
        EXPECT_EQ(h.out("normal").at(2, 0, 0), 0.f);
        EXPECT_EQ(h.out("normal").at(2, 1, 0), std::string(aa) == "false" ? -1.f : 0.f);
    }
}

// reflection: 1 where Denoising Normal names another surface than the Normal pass (or none): on
// blender-street the glass and the mirror sphere, a few percent of the frame.
TEST(ExrLoaderDenoisingData, ReflectionMarksWhereTheFeaturesPassAMirror) {
    const std::string dir = sharedData("blender-street");
    if (dir.empty() || !std::filesystem::exists(dir + "/noisy/frame_0005.exr"))
        GTEST_SKIP() << "../shared/data/blender-street not present";
    TempDir tmp("street-reflection");
    auto h = loadStreetSubset(dir, tmp, {"Combined.RGBA", "Normal.XYZ", "Denoising Normal.XYZ"},
                              "reflection");
    int marked = 0;
    for (int y = 0; y < 180; ++y)
        for (int x = 0; x < 320; ++x) {
            const float r = h.out("reflection").at(0, x, y);
            ASSERT_TRUE(r == 0.f || r == 1.f);
            marked += r == 1.f;
        }
    EXPECT_GT(marked, 2000);  // at least the ~2,000 surface pixels without a Denoising Normal
    EXPECT_LT(marked, 320 * 180 / 10);
}

// pathLength: Cycles' Denoising Depth as written (0 on the background), beside a planar Depth
// pass; where depth reads Denoising Depth itself (no Depth pass) pathLength is absent, saying
// which pass would give it, so the compiler leaves out VirtualMotion.
TEST(ExrLoaderDenoisingData, PathLengthIsDenoisingDepthBesideAPlanarDepth) {
    TempDir tmp("path-length");
    Channels ch;
    ch["ViewLayer.Depth.Z"] = {5.f, 1e10f};
    ch["ViewLayer.Denoising Depth.Z"] = {7.5f, 0.f};  // pixel 1 is background
    auto h = loaderOn(tmp, ch);
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    EXPECT_EQ(rc.absent.count("pathLength"), 0u);
    h.useOutputs({"depth", "pathLength"});
    h.ctx.frameNumber = 1;
    h.run();
    EXPECT_EQ(h.out("depth").at(0, 0, 0), 5.f);
    EXPECT_EQ(h.out("pathLength").at(0, 0, 0), 7.5f);
    EXPECT_EQ(h.out("pathLength").at(0, 1, 0), 0.f);  // background stays 0, not 1e10
}

TEST(ExrLoaderDenoisingData, PathLengthAbsentWhereDepthIsThePathLength) {
    for (bool withDenoisingDepth : {true, false}) {
        TempDir tmp("no-path-length");
        Channels ch;
        if (withDenoisingDepth) ch["ViewLayer.Denoising Depth.Z"] = {7.5f, 0.f};
        auto h = loaderOn(tmp, ch);
        RecordingResolve rc(1);
        h.pass().resolve(rc);
        SCOPED_TRACE(withDenoisingDepth ? "Denoising Depth only" : "neither depth");
        ASSERT_EQ(rc.absent.count("pathLength"), 1u);
        EXPECT_NE(rc.absent["pathLength"].find("enable View Layer > Passes > Data > Z"),
                  std::string::npos);
    }
}

// On the showroom's mirror panel Denoising Depth describes the reflected surface: there the
// path length is longer than the planar depth (README: ~1.3x at the median), so pathLength is
// no copy of depth where reflection is set.
TEST(ExrLoaderDenoisingData, PathLengthOnTheShowroomMirrorIsLongerThanDepth) {
    const std::string dir = sharedData("blender-showroom");
    if (dir.empty() || !std::filesystem::exists(dir + "/noisy/frame_0005.exr"))
        GTEST_SKIP() << "../shared/data/blender-showroom not present";
    auto h = PassHarness::make<ExrLoader>({1, 1}, {{"path", dir + "/noisy/frame_####.exr"}});
    h.useOutputs({"depth", "pathLength", "reflection"});
    h.ctx.frameNumber = 5;
    h.run();
    std::vector<float> ratio;
    for (int y = 0; y < 180; ++y)
        for (int x = 0; x < 320; ++x) {
            const float d = h.out("depth").at(0, x, y), l = h.out("pathLength").at(0, x, y);
            if (h.out("reflection").at(0, x, y) == 1.f && d > 0.f && d < 1e9f && l > 0.f)
                ratio.push_back(l / d);
        }
    ASSERT_GT(ratio.size(), 1000u);
    std::nth_element(ratio.begin(), ratio.begin() + ratio.size() / 2, ratio.end());
    EXPECT_GT(ratio[ratio.size() / 2], 1.1f);
}
