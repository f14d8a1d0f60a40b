// The files writeSequence produces: the canonical layout (docs/canonical-layout.md) and the
// GAMES202 homework layout (../shared/data/README.md, `games202-box`).
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <gtest/gtest.h>
#include <scenegen/SceneGen.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>

#include "ExrRead.h"

using namespace kestrel::scenegen;
namespace fs = std::filesystem;

namespace {

fs::path freshDir(const std::string& name) {
    const fs::path dir = fs::temp_directory_path() / ("kestrel_scenegen_test_" + name);
    fs::remove_all(dir);
    return dir;
}

SceneOptions tiny() {
    SceneOptions o;
    o.width = 32;
    o.height = 24;
    o.frames = 2;
    o.referenceSpp = 4;
    return o;
}

std::vector<char> readBytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST(SceneGenFiles, CanonicalLayoutHasEveryChannelAndTheMatrices) {
    const SceneOptions o = tiny();
    const fs::path dir = freshDir("canonical");
    const WriteStats stats = writeSequence(o, dir);
    EXPECT_EQ(stats.filesWritten, 4);
    EXPECT_EQ(stats.framesWritten, 2);
    ASSERT_TRUE(fs::exists(dir / "noisy/frame_0001.exr"));
    ASSERT_TRUE(fs::exists(dir / "noisy/frame_0002.exr"));
    ASSERT_TRUE(fs::exists(dir / "ref/frame_0002.exr"));

    const ExrImage img = readExr(dir / "noisy/frame_0002.exr");
    const std::vector<std::string> expected = {
        "B",          "G",           "R",          "albedo.B",   "albedo.G",
        "albedo.R",   "depth.Z",     "direct.B",   "direct.G",   "direct.R",
        "emission.B", "emission.G",  "emission.R", "indirect.B", "indirect.G",
        "indirect.R", "motion.X",    "motion.Y",   "normal.X",   "normal.Y",
        "normal.Z",   "objectId.id", "position.X", "position.Y", "position.Z"};
    EXPECT_EQ(channelNames(img), expected);
    for (const auto& [name, type] : img.types) EXPECT_EQ(type, int(Imf::FLOAT)) << name;
    EXPECT_EQ(img.header.compression(), Imf::ZIP_COMPRESSION);

    // Pixels equal the in-memory frame (row 0 = top); objectId is the integer id as a float.
    const FrameAovs f = renderFrame(o, 2);
    const size_t n = f.objectId.size();
    for (size_t k = 0; k < n; ++k) {
        ASSERT_EQ(img.channels.at("R")[k], f.color[0][k]);
        ASSERT_EQ(img.channels.at("motion.Y")[k], f.motion[1][k]);
        ASSERT_EQ(img.channels.at("objectId.id")[k], float(f.objectId[k]));
        ASSERT_EQ(img.channels.at("depth.Z")[k], f.depth[k]);
    }

    const auto* layout = img.header.findTypedAttribute<Imf::StringAttribute>("kestrel.layout");
    ASSERT_NE(layout, nullptr);
    EXPECT_EQ(layout->value(), "canonical");
    const auto* version = img.header.findTypedAttribute<Imf::IntAttribute>("kestrel.layoutVersion");
    ASSERT_NE(version, nullptr);
    EXPECT_EQ(version->value(), 1);
    // M44f x[row][col] holds our row-major, column-vector matrix element (row, col).
    const auto* w2p = img.header.findTypedAttribute<Imf::M44fAttribute>("kestrel.worldToPixel");
    ASSERT_NE(w2p, nullptr);
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) EXPECT_EQ(w2p->value()[r][c], f.worldToPixel.m[r][c]);
    ASSERT_NE(img.header.findTypedAttribute<Imf::M44fAttribute>("kestrel.worldToCamera"), nullptr);
    for (int id = 0; id < objectCount(); ++id) {
        const auto* m = img.header.findTypedAttribute<Imf::M44fAttribute>("kestrel.objectToWorld." +
                                                                          std::to_string(id));
        ASSERT_NE(m, nullptr) << id;
        EXPECT_EQ(m->value()[0][3], f.objectToWorld.at(id).m[0][3]);
    }

    const ExrImage ref = readExr(dir / "ref/frame_0002.exr");
    EXPECT_EQ(channelNames(ref), (std::vector<std::string>{"B", "G", "R"}));
    const auto* refLayout = ref.header.findTypedAttribute<Imf::StringAttribute>("kestrel.layout");
    ASSERT_NE(refLayout, nullptr);
    EXPECT_EQ(refLayout->value(), "canonical");
    const std::vector<float> expectRef = renderReference(o, 2);
    for (size_t k = 0; k < n; ++k) ASSERT_EQ(ref.channels.at("G")[k], expectRef[n + k]);

    // Deterministic files: a second run writes the same bytes.
    const fs::path again = freshDir("canonical_again");
    writeSequence(o, again);
    EXPECT_EQ(readBytes(dir / "noisy/frame_0001.exr"), readBytes(again / "noisy/frame_0001.exr"));
    EXPECT_EQ(readBytes(dir / "ref/frame_0001.exr"), readBytes(again / "ref/frame_0001.exr"));
    // No temporary file left behind.
    for (const auto& e : fs::recursive_directory_iterator(dir))
        EXPECT_NE(e.path().extension(), ".tmp") << e.path();
    fs::remove_all(dir);
    fs::remove_all(again);
}

TEST(SceneGenFiles, StreetFilesHaveTheDiffuseSpecularSplit) {
    SceneOptions o = zooScene("street").options;
    o.width = 48;
    o.height = 32;
    o.frames = 1;
    o.referenceSpp = 2;
    const fs::path dir = freshDir("street");
    writeSequence(o, dir);
    const ExrImage img = readExr(dir / "noisy/frame_0001.exr");
    const FrameAovs f = renderFrame(o, 1);
    const size_t n = f.objectId.size();
    // The names the canonical loader reads (passes/exr/ChannelPlan.cpp, planCanonical).
    for (const char* group : {"diffuse", "diffuseAlbedo", "specular", "specularAlbedo"})
        for (const char* c : {".R", ".G", ".B"})
            ASSERT_EQ(img.channels.count(std::string(group) + c), 1u) << group << c;
    for (size_t k = 0; k < n; ++k) {
        ASSERT_EQ(img.channels.at("specular.G")[k], f.specular[1][k]);
        ASSERT_EQ(img.channels.at("specularAlbedo.R")[k], f.specularAlbedo[0][k]);
        ASSERT_EQ(img.channels.at("diffuse.B")[k], f.diffuse[2][k]);
    }
    EXPECT_EQ(int(img.channels.count("objectId.id")), 1);
    const auto* m = img.header.findTypedAttribute<Imf::M44fAttribute>(
        "kestrel.objectToWorld." + std::to_string(objectCount(o) - 1));
    EXPECT_NE(m, nullptr) << "one matrix per street object";
    fs::remove_all(dir);

    o.omit = {"specular", "specularAlbedo"};
    writeSequence(o, dir);
    const ExrImage without = readExr(dir / "noisy/frame_0001.exr");
    EXPECT_EQ(without.channels.count("specular.R"), 0u);
    EXPECT_EQ(without.channels.count("specularAlbedo.R"), 0u);
    EXPECT_EQ(without.channels.count("diffuse.R"), 1u);
    fs::remove_all(dir);
}

TEST(SceneGenFiles, OmittedAovsAreAbsent) {
    SceneOptions o = tiny();
    o.frames = 1;
    o.omit = {"albedo", "motion", "direct", "indirect", "camera"};
    const fs::path dir = freshDir("omit");
    writeSequence(o, dir);
    const ExrImage img = readExr(dir / "noisy/frame_0001.exr");
    for (const auto& name : channelNames(img)) {
        EXPECT_EQ(name.rfind("albedo.", 0), std::string::npos) << name;
        EXPECT_EQ(name.rfind("motion.", 0), std::string::npos) << name;
        EXPECT_EQ(name.rfind("direct.", 0), std::string::npos) << name;
        EXPECT_EQ(name.rfind("indirect.", 0), std::string::npos) << name;
    }
    EXPECT_EQ(img.channels.count("emission.R"), 1u);
    EXPECT_EQ(img.channels.count("normal.X"), 1u);
    EXPECT_EQ(img.header.findTypedAttribute<Imf::M44fAttribute>("kestrel.worldToCamera"), nullptr);
    EXPECT_EQ(img.header.findTypedAttribute<Imf::M44fAttribute>("kestrel.objectToWorld.0"),
              nullptr);
    EXPECT_NE(img.header.findTypedAttribute<Imf::StringAttribute>("kestrel.layout"), nullptr);
    fs::remove_all(dir);

    o.omit = {"albedo", "normals"};  // misspelt: rejected, nothing written
    EXPECT_THROW(writeSequence(o, freshDir("omit_bad")), std::invalid_argument);
}

TEST(SceneGenFiles, Games202LayoutMatchesTheHomeworkFiles) {
    SceneOptions o = tiny();
    o.layout = SceneOptions::Layout::Games202;
    o.firstFrame = 0;
    const fs::path dir = freshDir("games202");
    const WriteStats stats = writeSequence(o, dir);
    EXPECT_EQ(stats.filesWritten, 2 * 7);
    for (const char* f : {"beauty_0.exr", "normal_1.exr", "position_1.exr", "depth_1.exr",
                          "ID_1.exr", "matrix_1.mat", "reference/beauty_1.exr"})
        EXPECT_TRUE(fs::exists(dir / f)) << f;

    // Same channels, types and compression as the homework's own files.
    const fs::path real = fs::path(KESTREL_SHARED_DIR) / "data/games202-box";
    const bool haveReal = fs::exists(real / "beauty_0.exr");
    for (const char* stem : {"beauty", "normal", "position", "depth", "ID"}) {
        const ExrImage mine = readExr(dir / (std::string(stem) + "_1.exr"));
        EXPECT_EQ(mine.header.compression(), Imf::ZIP_COMPRESSION);
        for (const auto& [name, type] : mine.types) EXPECT_EQ(type, int(Imf::FLOAT)) << stem;
        if (haveReal) {
            const ExrImage theirs = readExr(real / (std::string(stem) + "_0.exr"));
            EXPECT_EQ(channelNames(mine), channelNames(theirs)) << stem;
            EXPECT_EQ(mine.header.compression(), theirs.header.compression()) << stem;
            EXPECT_EQ(mine.header.lineOrder(), theirs.header.lineOrder()) << stem;
        }
    }

    // matrix_1.mat: int32 N, N object-to-world, world-to-camera (z forward), world-to-screen.
    const std::vector<char> bytes = readBytes(dir / "matrix_1.mat");
    int32_t count = 0;
    ASSERT_GE(bytes.size(), 4u);
    std::memcpy(&count, bytes.data(), 4);
    ASSERT_EQ(count, objectCount());
    ASSERT_EQ(bytes.size(), 4u + size_t(count + 2) * 64u);
    auto matrix = [&](int index) {
        Mat4 m;
        std::memcpy(m.m.data(), bytes.data() + 4 + size_t(index) * 64, 64);
        return m;
    };
    const Mat4 view = matrix(count), screen = matrix(count + 1);
    const ExrImage pos = readExr(dir / "position_1.exr");
    const ExrImage depth = readExr(dir / "depth_1.exr");
    const ExrImage id = readExr(dir / "ID_1.exr");
    float maxPixelErr = 0, maxDepthErr = 0;
    int background = 0;
    for (int j = 0; j < pos.height; ++j)
        for (int i = 0; i < pos.width; ++i) {
            const size_t k = size_t(j) * size_t(pos.width) + size_t(i);
            const float x = pos.channels.at("R")[k], y = pos.channels.at("G")[k],
                        z = pos.channels.at("B")[k];
            if (id.channels.at("Y")[k] == -1.f) {
                ++background;
                EXPECT_EQ(depth.channels.at("Y")[k], 0.f);
                continue;
            }
            const kestrel::Vec4 s = screen.transformPoint({x, y, z});
            const float w = s.w, sx = s.x / w, sy = s.y / w;
            const float zc = view.transformPoint({x, y, z}).z;
            maxPixelErr =
                std::max({maxPixelErr, std::fabs(sx - (i + 0.5f)), std::fabs(sy - (j + 0.5f))});
            maxDepthErr = std::max({maxDepthErr, std::fabs(zc - depth.channels.at("Y")[k]),
                                    std::fabs(w - depth.channels.at("Y")[k])});
        }
    // Measured: 5.7e-6 px, 9.5e-7 m.
    EXPECT_LT(maxPixelErr, 2e-3f);
    EXPECT_LT(maxDepthErr, 1e-4f);
    EXPECT_GT(background, 0);
    fs::remove_all(dir);
}
