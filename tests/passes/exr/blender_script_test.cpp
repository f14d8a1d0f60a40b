// scripts/blender/kestrel_setup.py (docs/blender.md): the camera.json it writes is what the
// loader reads. Its matrix math and document are plain Python, run here under python3 on an
// analytic camera; the whole script runs under Blender where `blender` is installed.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "SceneMatrices.h"
#include "TempDir.h"

using namespace kestrel;

namespace {

namespace fs = std::filesystem;

const fs::path kScript = fs::path(KESTREL_SOURCE_DIR) / "scripts" / "blender" / "kestrel_setup.py";

bool onPath(const char* tool) {
    return std::system(("command -v " + std::string(tool) + " >/dev/null 2>&1").c_str()) == 0;
}

/// Pixel (x, y) and camera-space z of world point p.
struct Projected {
    double x, y, zCamera;
};
Projected project(const SceneData& s, double px, double py, double pz) {
    double clip[4], cam[4];
    for (int r = 0; r < 4; ++r) {
        const auto& m = s.worldToPixel.m[r];
        const auto& v = s.worldToCamera.m[r];
        clip[r] = m[0] * px + m[1] * py + m[2] * pz + m[3];
        cam[r] = v[0] * px + v[1] * py + v[2] * pz + v[3];
    }
    return {clip[0] / clip[3], clip[1] / clip[3], cam[2]};
}

// The script's writer, fed the camera Blender would give: 64x48, a 60 degree horizontal field
// of view, at (1, -5, 2) looking along +Y (rotated 90 degrees about X) with a scale of 2 on its
// object (Blender cameras can be scaled; the view stays rigid), moving +1 in x by frame 2.
const char* kWriter = R"PY(
import math, sys
sys.path.insert(0, sys.argv[1])
import kestrel_setup as k
proj = k.perspective(math.radians(60), 64, 48, 0.1, 100.0)
frames = []
for f, x in ((1, 1.0), (2, 2.0)):
    cam = [[2, 0, 0, x], [0, 0, -2, -5], [0, 2, 0, 2], [0, 0, 0, 1]]
    cube = [[1, 0, 0, 0], [0, 1, 0, 7], [0, 0, 1, 0.5], [0, 0, 0, 1]]
    frames.append(k.frame_entry(f, cam, proj, {"Cube": cube, "Unindexed": cube}))
doc = k.camera_document(frames, (64, 48), math.radians(60), 0.0, 0.1, 100.0, {"Cube": 3},
                        k.filter_settings("BLACKMAN_HARRIS", 0.01))
k.write_camera_json(sys.argv[2], doc)
)PY";

}  // namespace

TEST(BlenderScript, CameraJsonItWritesIsWhatTheLoaderReads) {
    if (!onPath("python3")) GTEST_SKIP() << "python3 is not installed";
    const fs::path dir = testutil::processTempDir() / "blender-script";
    fs::create_directories(dir);
    const fs::path writer = dir / "writer.py", json = dir / "out" / "camera.json";
    std::ofstream(writer) << kWriter;
    const std::string cmd = "python3 -B '" + writer.string() + "' '" +
                            kScript.parent_path().string() + "' '" + json.string() + "'";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;

    const exr::BlenderCameras cams(json);
    ASSERT_TRUE(cams.pixelFilterWidth().has_value());
    EXPECT_NEAR(*cams.pixelFilterWidth(), 0.01f, 1e-6f);
    SceneData s;
    ASSERT_TRUE(cams.fill(1, s));
    EXPECT_TRUE(s.hasCamera);
    // 10 m ahead of the camera: the image centre, planar depth 10 (camera z = -10).
    Projected c = project(s, 1, 5, 2);
    EXPECT_NEAR(c.x, 32, 1e-3);
    EXPECT_NEAR(c.y, 24, 1e-3);
    EXPECT_NEAR(c.zCamera, -10, 1e-4);
    // tan(30 degrees) * 10 m to the right: the right edge; 1 m up: above the centre (y down).
    Projected r = project(s, 1 + 10 * std::tan(M_PI / 6), 5, 3);
    EXPECT_NEAR(r.x, 64, 1e-3);
    EXPECT_NEAR(r.y, 24 - 32 / (10 * std::tan(M_PI / 6)), 1e-3);
    // Frame 2: the camera moved +1 in x, so the point 1 m to the right is centred.
    ASSERT_TRUE(cams.fill(2, s));
    EXPECT_NEAR(project(s, 2, 5, 2).x, 32, 1e-3);
    // Objects by pass index; an object without one is not listed.
    ASSERT_EQ(s.objectToWorld.size(), 1u);
    EXPECT_FLOAT_EQ(s.objectToWorld.at(3).m[1][3], 7.f);
    EXPECT_FALSE(cams.fill(3, s));  // the range written, no more
}

TEST(BlenderScript, RunsInBlenderOnTheDefaultScene) {
    if (!onPath("blender"))
        GTEST_SKIP() << "blender is not installed (Debian: apt-get install blender); the "
                        "script's camera.json writer is tested without it";
    const fs::path dir = testutil::processTempDir() / "blender-run";
    const std::string cmd = "blender -b --factory-startup --python '" + kScript.string() +
                            "' -- '" + dir.string() + "' --frames 1-2 --filter-width 0.01" + " >'" +
                            (dir.string() + ".log") + "' 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    const exr::BlenderCameras cams(dir / "camera.json");
    SceneData s;
    EXPECT_TRUE(cams.fill(1, s));
    EXPECT_TRUE(cams.fill(2, s));
    EXPECT_FALSE(cams.fill(3, s));
    ASSERT_TRUE(cams.pixelFilterWidth().has_value());
    EXPECT_NEAR(*cams.pixelFilterWidth(), 0.01f, 1e-6f);
}
