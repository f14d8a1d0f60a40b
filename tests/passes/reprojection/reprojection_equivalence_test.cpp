// Equivalence of the optimised Reprojection pass with the plain scalar reference
// (ReprojectionReference.h) on random and extreme inputs, every input combination and 1-3
// threads, on every compiled SIMD target this CPU supports (without FMA, SSE4 and the baseline,
// the pass takes its per-pixel path everywhere). Tolerance: exact (0 ulp, bitwise identical
// floats including the sign of zero).
#include <denoise/TapsMask.h>
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "../../ExtremeValues.h"
#include "../FactResolve.h"
#include "../SameBits.h"
#include "HwyTargets.h"
#include "ReprojectionPass.h"
#include "ReprojectionReference.h"
#include "ReprojectionScene.h"
#include "kestrel/Conventions.h"
#include "kestrel/testing/PassHarness.h"

using namespace kestrel;
using kestrel::testing::PassHarness;
using reprojscene::Frames;
using reprojscene::hash01;

using svgftest::sameBits;

namespace {

/// Which inputs are bound (history inputs: bound and valid).
struct Binding {
    bool objectId = true, motion = true, position = true, prevObjectId = true;
    bool prevColor = true, prevMoments = true, prevHistoryLength = true, cameras = false;
};

void setScenes(SceneData& cur, SceneData& prev) {
    cur.hasCamera = prev.hasCamera = true;
    // Previous pixel = perspective-ish map of the position: a shift, a shear and a w that
    // depends on z, so every matrix entry matters.
    prev.worldToPixel = Mat4::identity();
    prev.worldToPixel.m[0] = {1.01f, 0.02f, 0.003f, 1.3f};
    prev.worldToPixel.m[1] = {-0.01f, 0.99f, 0.002f, -0.4f};
    prev.worldToPixel.m[3] = {0.f, 0.f, -0.001f, 0.99f};
    prev.worldToCamera = Mat4::identity();
    prev.worldToCamera.m[2][3] = 0.05f;
    cur.worldToPixel = Mat4::identity();
    cur.worldToCamera = Mat4::identity();
    for (int id = 1; id <= 5; ++id) {
        Mat4 m = Mat4::identity();
        m.m[0][3] = 0.5f * float(id);
        m.m[1][3] = -0.25f * float(id);
        cur.objectToWorld[id] = m;
        if (id == 5) continue;  // only in this frame: the camera-only transform
        Mat4 p = Mat4::identity();
        p.m[0][3] = 0.5f * float(id) + 0.7f;
        p.m[1][3] = -0.25f * float(id) - 0.3f * float(id % 2);
        prev.objectToWorld[id] = p;
    }
    Mat4 singular{};  // not invertible: the camera-only transform
    cur.objectToWorld[3] = singular;
}

reprojref::Outputs runReference(const Frames& f, const Binding& b, const SceneData* cur,
                                const SceneData* prev, const reprojref::Params& p) {
    reprojref::Inputs in;
    in.depth = &f.depth;
    in.normal = &f.normal;
    in.objectId = b.objectId ? &f.objectId : nullptr;
    in.motion = b.motion ? &f.motion : nullptr;
    in.position = b.position ? &f.position : nullptr;
    in.prevDepth = &f.prevDepth;
    in.prevNormal = &f.prevNormal;
    in.prevObjectId = b.prevObjectId ? &f.prevObjectId : nullptr;
    in.prevColor = b.prevColor ? &f.prevColor : nullptr;
    in.prevMoments = b.prevMoments ? &f.prevMoments : nullptr;
    in.prevHistoryLength = b.prevHistoryLength ? &f.prevHistoryLength : nullptr;
    in.scene = cur;
    in.previousScene = prev;
    return reprojref::reproject(in, p);
}

/// The pass's parameters for the reference's: infinite thresholds are geometryTests off (the
/// reference runs them as tests no finite distance fails).
std::map<std::string, ParamValue> passParams(const reprojref::Params& p) {
    std::map<std::string, ParamValue> m{{"filter", p.catmullRom ? "catmullrom" : "bilinear"}};
    if (std::isinf(p.depthThreshold) && std::isinf(p.normalThreshold)) {
        m["geometryTests"] = false;
    } else {
        m["depthThreshold"] = double(p.depthThreshold);
        m["normalThreshold"] = double(p.normalThreshold);
    }
    return m;
}

/// Bitwise comparison; reports the first differing float.
void expectEquivalent(const Frames& f, const Binding& b, const reprojref::Params& p, int threads,
                      const std::string& what) {
    SCOPED_TRACE(what + (p.catmullRom ? " catmullrom" : " bilinear") + " threads " +
                 std::to_string(threads) + " thresholds " + std::to_string(p.depthThreshold) + " " +
                 std::to_string(p.normalThreshold));
    auto h = PassHarness::make<ReprojectionPass>(f.depth.extent(), passParams(p), threads);
    if (p.depthPrecision > 0.f) {
        svgftest::FactResolve facts(kDepthPrecisionFact, std::to_string(p.depthPrecision));
        h.pass().resolve(facts);
    }
    h.bind("depth", f.depth);
    h.bind("normal", f.normal);
    if (b.objectId) h.bind("objectId", f.objectId);
    if (b.motion) h.bind("motion", f.motion);
    if (b.position) h.bind("position", f.position);
    h.bind("prevDepth", f.prevDepth);
    h.bind("prevNormal", f.prevNormal);
    if (b.prevObjectId) h.bind("prevObjectId", f.prevObjectId);
    if (b.prevColor) h.bind("prevColor", f.prevColor);
    if (b.prevMoments) h.bind("prevMoments", f.prevMoments);
    if (b.prevHistoryLength) h.bind("prevHistoryLength", f.prevHistoryLength);
    if (b.cameras) setScenes(h.scene, h.previousScene);
    h.run();
    const auto ref = runReference(f, b, b.cameras ? &h.scene : nullptr,
                                  b.cameras ? &h.previousScene : nullptr, p);
    EXPECT_TRUE(sameBits(h.out("color"), ref.color)) << "color";
    EXPECT_TRUE(sameBits(h.out("moments"), ref.moments)) << "moments";
    EXPECT_TRUE(sameBits(h.out("historyLength"), ref.historyLength)) << "historyLength";
    EXPECT_EQ(std::memcmp(h.out("taps").view().ints(), ref.taps.view().ints(),
                          ref.taps.view().pixels() * sizeof(int32_t)),
              0)
        << "taps: the same bits on every path and target";

    // A second reprojection given this one's taps (as the specular chain takes the diffuse
    // chain's) gives the same outputs without testing: its own last-frame geometry is garbage,
    // which its tests would reject everywhere.
    auto shared = PassHarness::make<ReprojectionPass>(f.depth.extent(), passParams(p), threads);
    for (const char* port : {"depth", "normal", "objectId", "motion", "position", "prevColor",
                             "prevMoments", "prevHistoryLength"})
        if (h.hasInput(port)) shared.bind(port, h.input(port));
    Image nanDepth(f.depth.extent(), Format::Float), nanNormal(f.depth.extent(), Format::Float3);
    nanDepth.fill(std::numeric_limits<float>::quiet_NaN());
    nanNormal.fill(std::numeric_limits<float>::quiet_NaN());
    Image otherIds(f.depth.extent(), Format::Int32);
    std::fill_n(otherIds.view().ints(), otherIds.view().pixels(), 12345);
    shared.bind("prevDepth", nanDepth);
    shared.bind("prevNormal", nanNormal);
    if (b.prevObjectId) shared.bind("prevObjectId", otherIds);
    shared.bind("sharedTaps", h.out("taps"));
    shared.useOutputs({"color", "moments", "historyLength", "resampleBlur"});
    if (b.cameras) setScenes(shared.scene, shared.previousScene);
    shared.run();
    for (const char* port : {"color", "moments", "historyLength", "resampleBlur"}) {
        if (h.hasOutput(port)) {
            EXPECT_TRUE(sameBits(shared.out(port), h.out(port))) << "shared " << port;
        }
    }

    // One pixel marked untested (VirtualMotion moved its motion): the frame's taps are tested
    // again, so the garbage last-frame geometry is seen (no history survives it) ...
    Image marked(f.depth.extent(), Format::Int32);
    std::copy_n(h.out("taps").view().ints(), marked.view().pixels(), marked.view().ints());
    marked.view().ints()[marked.view().pixels() / 2] = taps::kUntested;
    shared.bind("sharedTaps", marked);
    shared.run();
    if (h.hasOutput("historyLength") &&
        (std::isfinite(p.depthThreshold) || std::isfinite(p.normalThreshold))) {
        const ImageView hl = shared.out("historyLength").view();
        EXPECT_EQ(*std::max_element(hl.channel(0), hl.channel(0) + hl.pixels()), 0.f)
            << "an untested pixel: the taps are tested here";
    }
    // ... and with the real geometry the outputs are the shared tests' (the same tests).
    shared.bind("prevDepth", f.prevDepth);
    shared.bind("prevNormal", f.prevNormal);
    if (b.prevObjectId) shared.bind("prevObjectId", f.prevObjectId);
    if (p.depthPrecision > 0.f) {
        svgftest::FactResolve facts(kDepthPrecisionFact, std::to_string(p.depthPrecision));
        shared.pass().resolve(facts);
    }
    shared.run();
    for (const char* port : {"color", "moments", "historyLength", "resampleBlur"}) {
        if (h.hasOutput(port)) {
            EXPECT_TRUE(sameBits(shared.out(port), h.out(port))) << "untested pixel " << port;
        }
    }

    // Without a consumer of taps the pass tests without recording (the single chain's and
    // TAA's mode): the same outputs.
    auto plain = PassHarness::make<ReprojectionPass>(f.depth.extent(), passParams(p), threads);
    for (const char* port :
         {"depth", "normal", "objectId", "motion", "position", "prevDepth", "prevNormal",
          "prevObjectId", "prevColor", "prevMoments", "prevHistoryLength"})
        if (h.hasInput(port)) plain.bind(port, h.input(port));
    plain.useOutputs({"color", "moments", "historyLength", "resampleBlur"});
    if (p.depthPrecision > 0.f) {
        svgftest::FactResolve facts(kDepthPrecisionFact, std::to_string(p.depthPrecision));
        plain.pass().resolve(facts);
    }
    if (b.cameras) setScenes(plain.scene, plain.previousScene);
    plain.run();
    for (const char* port : {"color", "moments", "historyLength", "resampleBlur"}) {
        if (h.hasOutput(port)) {
            EXPECT_TRUE(sameBits(plain.out(port), h.out(port))) << "untracked taps " << port;
        }
    }
}

void expectEquivalentAll(const Frames& f, const Binding& b, const std::string& what) {
    for (bool cr : {false, true})
        for (int threads : {1, 2, 3}) {
            reprojref::Params p;
            p.catmullRom = cr;
            expectEquivalent(f, b, p, threads, what);
        }
}

/// Overwrites about `fraction` of every float input's values with extreme ones.
void sprinkleExtremes(Frames& f, float fraction, int seed) {
    const std::vector<float> vals = testvalues::extremeValuesAnd({2.f, -2.5f, 1e10f, 1e7f, -1e7f});
    const int kVals = int(vals.size());
    int s = seed;
    for (Image* im : {&f.depth, &f.normal, &f.motion, &f.position, &f.prevDepth, &f.prevNormal,
                      &f.prevColor, &f.prevMoments, &f.prevHistoryLength}) {
        ++s;
        for (int c = 0; c < channelCount(im->format()); ++c)
            for (int y = 0; y < im->height(); ++y)
                for (int x = 0; x < im->width(); ++x)
                    if (hash01(x, y, s * 7 + c) < fraction)
                        im->at(c, x, y) = vals[int(hash01(x, y, s * 13 + c) * kVals)];
    }
    for (Image* im : {&f.objectId, &f.prevObjectId}) {
        ++s;
        for (int y = 0; y < im->height(); ++y)
            for (int x = 0; x < im->width(); ++x)
                if (hash01(x, y, s) < fraction) im->atInt(x, y) = int(hash01(x, y, s + 1) * 4) - 1;
    }
}

}  // namespace

class ReprojectionEquivalence : public kestrel::test::EveryTarget {};
KESTREL_FOR_EVERY_TARGET(ReprojectionEquivalence);

TEST_P(ReprojectionEquivalence, SceneWithMotionVectors) {
    for (int seed : {1, 2}) {
        const Frames f = reprojscene::makeFrames(97, 61, seed);
        expectEquivalentAll(f, {}, "scene seed " + std::to_string(seed));
    }
}

TEST_P(ReprojectionEquivalence, WideRowsInSeveralTiles) {
    // The pass works through a row in tiles of 256 pixels, the last taking the remainder: 1100
    // columns make four tiles with derivatives, runs and vectors crossing tile boundaries.
    Frames f = reprojscene::makeFrames(1100, 9, 13);
    sprinkleExtremes(f, 0.01f, 13);
    expectEquivalentAll(f, {}, "wide rows");
}

TEST_P(ReprojectionEquivalence, StaticAndFastScenes) {
    expectEquivalentAll(reprojscene::makeFrames(64, 40, 3, 0.f), {}, "static");
    expectEquivalentAll(reprojscene::makeFrames(64, 40, 4, 6.f), {}, "fast");
}

TEST_P(ReprojectionEquivalence, RandomMotionIncludingOffScreen) {
    Frames f = reprojscene::makeFrames(53, 47, 5);
    for (int y = 0; y < 47; ++y)
        for (int x = 0; x < 53; ++x) {
            // Mostly small, sometimes integer or half-integer, sometimes far off screen.
            const float r = hash01(x, y, 100);
            float mx = 8.f * hash01(x, y, 101) - 4.f, my = 8.f * hash01(x, y, 102) - 4.f;
            if (r < 0.1f) mx = std::round(mx), my = std::round(my);
            if (r >= 0.1f && r < 0.2f) mx = std::round(mx) + 0.5f, my = std::round(my) - 0.5f;
            if (r >= 0.2f && r < 0.25f) mx = 200.f * (hash01(x, y, 103) - 0.5f);
            f.motion.at(0, x, y) = mx;
            f.motion.at(1, x, y) = my;
        }
    expectEquivalentAll(f, {}, "random motion");
}

TEST_P(ReprojectionEquivalence, ExtremeValues) {
    for (float fraction : {0.02f, 0.2f}) {
        Frames f = reprojscene::makeFrames(61, 43, 6);
        sprinkleExtremes(f, fraction, int(fraction * 1000));
        expectEquivalentAll(f, {}, "extremes " + std::to_string(fraction));
        Binding m;
        m.motion = false;
        m.cameras = true;
        expectEquivalentAll(f, m, "extremes, matrices " + std::to_string(fraction));
    }
}

TEST_P(ReprojectionEquivalence, AllZeroAndDenormalInputs) {
    Frames f = reprojscene::makeFrames(40, 24, 7);
    for (Image* im : {&f.prevColor, &f.prevMoments, &f.prevHistoryLength}) im->fill(0.f);
    expectEquivalentAll(f, {}, "zero history");
    for (Image* im : {&f.prevColor, &f.prevMoments, &f.prevHistoryLength})
        im->fill(-std::numeric_limits<float>::denorm_min());
    expectEquivalentAll(f, {}, "negative denormal history");
    for (Image* im : {&f.depth, &f.prevDepth, &f.normal, &f.prevNormal}) im->fill(0.f);
    expectEquivalentAll(f, {}, "zero geometry");
}

TEST_P(ReprojectionEquivalence, MatrixAndIdentityPaths) {
    Frames f = reprojscene::makeFrames(71, 45, 8);
    for (int y = 0; y < 45; ++y)
        for (int x = 0; x < 71; ++x) f.objectId.atInt(x, y) = f.objectId.atInt(x, y) % 6 - 1;
    Binding m;
    m.motion = false;
    m.cameras = true;
    expectEquivalentAll(f, m, "matrices");
    m.objectId = false;
    expectEquivalentAll(f, m, "matrices without ids");
    Binding id;
    id.motion = id.position = false;
    expectEquivalentAll(f, id, "identity");
    id.position = true;  // position without cameras: identity too
    expectEquivalentAll(f, id, "position without cameras");
}

TEST_P(ReprojectionEquivalence, InputCombinations) {
    const Frames f = reprojscene::makeFrames(45, 33, 9);
    for (int mask = 0; mask < 32; ++mask) {
        Binding b;
        b.objectId = mask & 1;
        b.prevObjectId = mask & 2;
        b.prevColor = mask & 4;
        b.prevMoments = mask & 8;
        b.prevHistoryLength = mask & 16;
        expectEquivalentAll(f, b, "inputs mask " + std::to_string(mask));
    }
}

TEST_P(ReprojectionEquivalence, TinyImages) {
    for (auto [w, h] : {std::pair{1, 1}, {1, 7}, {9, 1}, {2, 2}, {3, 5}, {17, 3}}) {
        Frames f = reprojscene::makeFrames(w, h, 10, 0.3f);
        expectEquivalentAll(f, {}, std::to_string(w) + "x" + std::to_string(h));
    }
}

TEST_P(ReprojectionEquivalence, Thresholds) {
    // Infinite thresholds: geometryTests off (TAA's history; also with Catmull-Rom).
    constexpr float kOff = std::numeric_limits<float>::infinity();
    const Frames f = reprojscene::makeFrames(50, 30, 11);
    for (auto [dz, dn] : {std::pair{0.f, 0.f}, {0.5f, 0.1f}, {1e6f, 1e6f}, {kOff, kOff}})
        for (bool catmullRom : {false, true}) {
            reprojref::Params p;
            p.depthThreshold = dz;
            p.normalThreshold = dn;
            p.catmullRom = catmullRom;
            expectEquivalent(f, {}, p, 2, "thresholds");
            p.depthPrecision = 0.0009765625f;  // depth stored as half: the test widened
            expectEquivalent(f, {}, p, 2, "thresholds, half depth");
        }
}

namespace {
/// A Catmull-Rom or bilinear Reprojection of `f` with every input bound (motion vectors).
PassHarness motionReprojection(const Frames& f, const char* filter) {
    auto h = PassHarness::make<ReprojectionPass>(f.depth.extent(), {{"filter", filter}}, 2);
    for (auto [port, image] : {std::pair<const char*, const Image*>{"depth", &f.depth},
                               {"normal", &f.normal},
                               {"objectId", &f.objectId},
                               {"motion", &f.motion},
                               {"prevDepth", &f.prevDepth},
                               {"prevNormal", &f.prevNormal},
                               {"prevObjectId", &f.prevObjectId},
                               {"prevColor", &f.prevColor},
                               {"prevMoments", &f.prevMoments},
                               {"prevHistoryLength", &f.prevHistoryLength}})
        h.bind(port, *image);
    return h;
}

bool sameTaps(const PassHarness& a, const PassHarness& b) {
    const ImageView &ta = a.out("taps").view(), &tb = b.out("taps").view();
    return std::memcmp(ta.ints(), tb.ints(), ta.pixels() * sizeof(int32_t)) == 0;
}
}  // namespace

// A Catmull-Rom reprojection given the taps of a bilinear one (which never tested the outer 12)
// resamples bilinearly: what a bilinear reprojection of its own gives.
TEST_P(ReprojectionEquivalence, CatmullRomOnBilinearTapsResamplesBilinearly) {
    const Frames f = reprojscene::makeFrames(64, 40, 21);
    PassHarness bilinear = motionReprojection(f, "bilinear");
    bilinear.run();
    PassHarness shared = motionReprojection(f, "catmullrom");
    shared.bind("sharedTaps", bilinear.out("taps"));
    shared.useOutputs({"color", "moments", "historyLength", "resampleBlur"});
    shared.run();
    EXPECT_TRUE(sameBits(shared.out("color"), bilinear.out("color")));
    PassHarness own = motionReprojection(f, "catmullrom");
    own.run();
    EXPECT_FALSE(sameBits(own.out("color"), bilinear.out("color")));  // Catmull-Rom differs
}

// The taps do not depend on which outputs the producer feeds: without its colour consumed it
// still tests the outer Catmull-Rom taps that a consumer's colour needs.
TEST_P(ReprojectionEquivalence, TapsDoNotDependOnTheOutputsConsumed) {
    const Frames f = reprojscene::makeFrames(64, 40, 22);
    PassHarness all = motionReprojection(f, "catmullrom");
    all.run();
    PassHarness noColour = motionReprojection(f, "catmullrom");
    noColour.useOutputs({"moments", "historyLength", "taps"});
    noColour.run();
    EXPECT_TRUE(sameTaps(all, noColour));
}

namespace {
/// Planes that end exactly at a page no access is allowed to (PROT_NONE): a kernel that reads
/// past a plane's last pixel faults. Each plane has a mapping of its own.
class GuardedPlanes {
public:
    ~GuardedPlanes() {
        for (auto [p, n] : maps_) munmap(p, n);
    }
    /// A copy of `im` whose every plane ends against a guard page.
    ImageView copy(const Image& im) {
        ImageView v = im.view();
        for (int c = 0; c < im.view().channels(); ++c) {
            const size_t bytes = im.view().pixels() * sizeof(float);
            const size_t page = size_t(sysconf(_SC_PAGESIZE));
            const size_t body = (bytes + page - 1) / page * page, total = body + page;
            void* m =
                mmap(nullptr, total, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
            if (m == MAP_FAILED) throw std::bad_alloc();
            maps_.push_back({m, total});
            char* guard = static_cast<char*>(m) + body;
            mprotect(guard, page, PROT_NONE);
            float* plane = reinterpret_cast<float*>(guard - bytes);
            std::memcpy(plane, im.view().planes[size_t(c)], bytes);
            v.planes[size_t(c)] = plane;
        }
        return v;
    }

private:
    std::vector<std::pair<void*, size_t>> maps_;
};
}  // namespace

// Vector kernels may load a window wider than the lanes' taps (AVX-512: 32 columns of a row
// around a vector whose tap offsets differ by up to 13 columns): every read must stay inside
// the plane. Last frame's planes end against a guard page and the motion points the last rows'
// taps at the image's bottom right, so a window reaching past the last pixel faults. (The
// sanitizer stage builds one SIMD target only; this runs on every target the CPU has.)
TEST_P(ReprojectionEquivalence, WindowLoadsStayInsideThePlanes) {
    for (int w : {61, 64, 200}) {
        Frames f = reprojscene::makeFrames(w, 37, 21);
        for (int y = 0; y < 37; ++y)
            for (int x = 0; x < w; ++x) {
                // Offsets varying by a column over a vector, and rows pointing at the last row.
                f.motion.at(0, x, y) = 1.2f + 0.07f * float(x % 23);
                f.motion.at(1, x, y) = y >= 30 ? 2.6f - 0.05f * float(x % 17) : 0.4f;
            }
        GuardedPlanes guarded;
        for (bool cr : {false, true}) {
            auto h = PassHarness::make<ReprojectionPass>(
                f.depth.extent(), {{"filter", cr ? "catmullrom" : "bilinear"}}, 2);
            h.bind("depth", f.depth);
            h.bind("normal", f.normal);
            h.bind("objectId", f.objectId);
            h.bind("motion", f.motion);
            h.bind("prevDepth", guarded.copy(f.prevDepth));
            h.bind("prevNormal", guarded.copy(f.prevNormal));
            h.bind("prevObjectId", guarded.copy(f.prevObjectId));
            h.bind("prevColor", guarded.copy(f.prevColor));
            h.bind("prevMoments", guarded.copy(f.prevMoments));
            h.bind("prevHistoryLength", guarded.copy(f.prevHistoryLength));
            h.run();  // a read past a plane's end faults here
            reprojref::Params p;
            p.catmullRom = cr;
            Binding b;
            b.position = false;
            const auto ref = runReference(f, b, nullptr, nullptr, p);
            EXPECT_TRUE(sameBits(h.out("color"), ref.color)) << "width " << w;
        }
    }
}
