// docs/design.md section 8 on the SVGF and GAMES202 graphs: hand-made extreme AOVs injected at
// exact pixels through the test source. Every case asserts: each frame's output finite and inside
// the plausible range of the input radiance after sanitising (NaN/Inf become 0), and the same bits
// with 1 and 2 threads.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include "Checks.h"

namespace stability {
namespace {

using kestrel::Extent;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr int kFrames = 8;

struct Case {
    std::string name;
    std::function<void(int64_t, Frame&)> modify;
    float lo = kPlainLo, hi = kPlainHi;
    Extent extent{48, 32};
};

void setRgb(Frame& f, const char* port, int x, int y, float r, float g, float b) {
    f[port].at(0, x, y) = r;
    f[port].at(1, x, y) = g;
    f[port].at(2, x, y) = b;
}

/// Runs both graphs on the case with 1 and 2 threads.
void runCase(const Case& c) {
    for (const char* graph : {"svgf", "jbf"}) {
        SCOPED_TRACE(std::string(graph) + " / " + c.name);
        const std::string scenario = c.name + "-" + graph;
        setScenario(scenario, plainScene(c.extent, c.modify));
        const TestGraph g = std::string(graph) == "svgf" ? svgfGraph(scenario) : jbfGraph(scenario);
        const Checked one = runBounded(g, kFrames, c.lo, c.hi, 1, c.name);
        const Checked two = runBounded(g, kFrames, c.lo, c.hi, 2, c.name);
        EXPECT_TRUE(bitwiseEqual(one.last, two.last)) << "1 vs 2 threads differ";
    }
}

TEST(ExtremeInputs, NanAndInfRadiance) {
    // NaN, +Inf and -Inf in single pixels every frame, a whole NaN row on frame 2: sanitised to
    // 0, so the output range widens down to 0 and no further.
    runCase({"naninf",
             [](int64_t frame, Frame& f) {
                 setRgb(f, "color", 5, 5, kNaN, kNaN, kNaN);
                 setRgb(f, "color", 10, 7, kInf, kInf, kInf);
                 setRgb(f, "color", 20, 20, -kInf, -kInf, -kInf);
                 setRgb(f, "color", 30, 10, kNaN, kInf, -kInf);
                 if (frame == 2)
                     for (int x = 0; x < 48; ++x) setRgb(f, "color", x, 25, kNaN, kNaN, kNaN);
             },
             0.f, kPlainHi});
}

TEST(ExtremeInputs, NegativeRadiance) {
    // A negated left half and one -1e3 pixel: the output stays within [-1e3, max].
    runCase({"negative",
             [](int64_t, Frame& f) {
                 for (int y = 0; y < 32; ++y)
                     for (int x = 0; x < 24; ++x)
                         for (int c = 0; c < 3; ++c) f["color"].at(c, x, y) *= -1.f;
                 setRgb(f, "color", 30, 16, -1e3f, -1e3f, -1e3f);
             },
             -1e3f, kPlainHi});
}

TEST(ExtremeInputs, AlbedoZeroUnderNonZeroColour) {
    // Black albedo on the left half under ordinary radiance, beside albedo 0.5 on the same
    // surface. Channels below the albedo floor are not demodulated (kestrel::px::
    // demodulationAlbedo): dividing by the floor used to amplify them 1000x, and SVGF's filters
    // spread that into the lit side (output 21.1 for inputs <= 1.55). Now the output stays in
    // the input's range: measured [0.44, 0.97] over 60 frames.
    auto modify = [](int64_t, Frame& f) {
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 24; ++x) setRgb(f, "albedo", x, y, 0.f, 0.f, 0.f);
    };
    for (const char* graph : {"svgf", "jbf"}) {
        SCOPED_TRACE(graph);
        const std::string scenario = std::string("albedo0-") + graph;
        setScenario(scenario, plainScene({48, 32}, modify));
        const TestGraph g = std::string(graph) == "svgf" ? svgfGraph(scenario) : jbfGraph(scenario);
        const float hi = kPlainHi;
        const Checked one = runBounded(g, 60, 0.f, hi, 1, "albedo0");
        std::printf("%s albedo 0: output range [%g, %g] over 60 frames\n", graph, one.worst.min,
                    one.worst.max);
        const Checked two = runBounded(g, 12, 0.f, hi, 2, "albedo0");
        const Checked oneShort = runBounded(g, 12, 0.f, hi, 1, "albedo0");
        EXPECT_TRUE(bitwiseEqual(oneShort.last, two.last)) << "1 vs 2 threads differ";
    }
}

TEST(ExtremeInputs, AntiAliasedAlbedoWithZeroNanAndInf) {
    // An anti-aliased render (the source offers jitteredAlbedo): svgf.json demodulates by the
    // albedo averaged over frames. Its samples flicker between two texels every frame, and hold
    // 0, NaN and +-Inf in single pixels: the average is sanitised and the output stays in the
    // input's range, the same for 1 and 2 threads. The colour is the sample's albedo times the
    // plain scene's light (as a renderer's is), so the input spans 0.4x..1.6x the plain range.
    auto modify = [](int64_t frame, Frame& f) {
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 48; ++x) {
                const float a = ((x + y + int(frame)) & 1) ? 0.2f : 0.8f;
                setRgb(f, "jitteredAlbedo", x, y, a, a, a);
                setRgb(f, "albedo", x, y, a, a, a);
                for (int c = 0; c < 3; ++c) f["color"].at(c, x, y) *= 2.f * a;
            }
        setRgb(f, "jitteredAlbedo", 4, 4, 0.f, 0.f, 0.f);
        setRgb(f, "jitteredAlbedo", 9, 6, kNaN, kNaN, kNaN);
        setRgb(f, "jitteredAlbedo", 20, 9, kInf, -kInf, kInf);
    };
    Scenario sc = plainScene({48, 32}, modify);
    sc.provides.insert("jitteredAlbedo");
    setScenario("aa-albedo", sc);
    const TestGraph g = svgfGraph("aa-albedo");
    const Checked one = runBounded(g, kFrames, 0.f, 1.6f * kPlainHi, 1, "aa-albedo");
    const Checked two = runBounded(g, kFrames, 0.f, 1.6f * kPlainHi, 2, "aa-albedo");
    std::printf("anti-aliased albedo: output range [%g, %g]\n", one.worst.min, one.worst.max);
    EXPECT_TRUE(bitwiseEqual(one.last, two.last)) << "1 vs 2 threads differ";
}

TEST(ExtremeInputs, LightThroughMirrorWithZeroNanAndInf) {
    // The loader's lightThroughMirror (KeepExact keeps the 1-spp colour of a uniform view through
    // a mirror): a block of uniform colour on the mask, the mask holding 0, NaN, +-Inf and 2 in
    // single pixels and the block's colour NaN and +-Inf in others. Kept pixels are the input's
    // own values, the rest filtered: the output stays finite, in the input's sanitised range,
    // the same for 1 and 2 threads.
    auto modify = [](int64_t, Frame& f) {
        const bool mask = f.images.count("lightThroughMirror") > 0;  // not in the control
        for (int y = 8; y < 24; ++y)
            for (int x = 10; x < 30; ++x) {
                if (mask) f["lightThroughMirror"].at(0, x, y) = 1.f;
                setRgb(f, "color", x, y, 1.f, 1.f, 1.f);
            }
        const float masks[] = {0.f, kNaN, kInf, -kInf, 2.f};
        for (int i = 0; mask && i < 5; ++i)
            f["lightThroughMirror"].at(0, 12 + 3 * i, 10) = masks[i];
        setRgb(f, "color", 14, 16, kNaN, kNaN, kNaN);
        setRgb(f, "color", 20, 18, kInf, -kInf, kInf);
        setRgb(f, "color", 25, 20, 0.f, 0.f, 0.f);
    };
    Scenario sc = plainScene({48, 32}, modify);
    sc.provides.insert("lightThroughMirror");
    setScenario("light-through-mirror", sc);
    const TestGraph g = svgfGraph("light-through-mirror");
    const Checked one = runBounded(g, kFrames, 0.f, kPlainHi, 1, "light-through-mirror");
    const Checked two = runBounded(g, kFrames, 0.f, kPlainHi, 2, "light-through-mirror");
    EXPECT_TRUE(bitwiseEqual(one.last, two.last)) << "1 vs 2 threads differ";
    // The block's inside is kept as rendered (1.0), which the filters alone do not give: the
    // same scenario without the mask is the control.
    const size_t pixels = 48 * 32, at = size_t(12) * 48 + 20;  // planar: channel c at c pixels
    for (size_t c = 0; c < 3; ++c) EXPECT_EQ(one.last[c * pixels + at], 1.f) << c;
    sc.provides.erase("lightThroughMirror");
    setScenario("light-through-mirror-off", sc);
    const Checked off = runBounded(svgfGraph("light-through-mirror-off"), kFrames, 0.f, kPlainHi, 1,
                                   "light-through-mirror-off");
    EXPECT_NE(off.last[at], 1.f) << "the control: filtered, not kept";
}

TEST(ExtremeInputs, AntiAliasedSplitAlbedosWithZeroNanAndInf) {
    // The same with the diffuse/specular split (a Blender render with a 1.5 px filter): each
    // chain averages its own albedo, and TAA runs (the loader offers jitteredAlbedo with the
    // split's). The specular part is a tenth of the colour, under white.
    auto modify = [](int64_t frame, Frame& f) {
        for (int y = 0; y < 32; ++y)
            for (int x = 0; x < 48; ++x) {
                const float a = ((x + y + int(frame)) & 1) ? 0.2f : 0.8f;
                for (const char* port :
                     {"albedo", "jitteredAlbedo", "diffuseAlbedo", "jitteredDiffuseAlbedo"})
                    setRgb(f, port, x, y, a, a, a);
                setRgb(f, "specularAlbedo", x, y, 1.f, 1.f, 1.f);
                setRgb(f, "jitteredSpecularAlbedo", x, y, 1.f, 1.f, 1.f);
                for (int c = 0; c < 3; ++c) {
                    const float v = f["color"].at(c, x, y) * 2.f * a;
                    f["color"].at(c, x, y) = v;
                    f["diffuse"].at(c, x, y) = 0.9f * v;
                    f["specular"].at(c, x, y) = 0.1f * v;
                }
            }
        for (const char* port : {"jitteredDiffuseAlbedo", "jitteredSpecularAlbedo"}) {
            setRgb(f, port, 4, 4, 0.f, 0.f, 0.f);
            setRgb(f, port, 9, 6, kNaN, kNaN, kNaN);
            setRgb(f, port, 20, 9, kInf, -kInf, kInf);
        }
    };
    Scenario sc = plainScene({48, 32}, modify);
    for (const char* port : {"diffuse", "specular", "diffuseAlbedo", "specularAlbedo",
                             "jitteredAlbedo", "jitteredDiffuseAlbedo", "jitteredSpecularAlbedo"})
        sc.provides.insert(port);
    setScenario("aa-split", sc);
    const TestGraph g = svgfGraph("aa-split");
    const Checked one = runBounded(g, kFrames, 0.f, 1.6f * kPlainHi, 1, "aa-split");
    const Checked two = runBounded(g, kFrames, 0.f, 1.6f * kPlainHi, 2, "aa-split");
    std::printf("anti-aliased split: output range [%g, %g]\n", one.worst.min, one.worst.max);
    EXPECT_TRUE(bitwiseEqual(one.last, two.last)) << "1 vs 2 threads differ";
}

TEST(ExtremeInputs, BackgroundPixels) {
    // Right quarter is background (depth 1e10, zero normal, id -1, albedo 0) with sky radiance.
    runCase({"background", [](int64_t, Frame& f) {
                 for (int y = 0; y < 32; ++y)
                     for (int x = 36; x < 48; ++x) {
                         f["depth"].at(0, x, y) = kestrel::kBackgroundDepth;
                         setRgb(f, "normal", x, y, 0.f, 0.f, 0.f);
                         setRgb(f, "albedo", x, y, 0.f, 0.f, 0.f);
                         f["objectId"].atInt(x, y) = kestrel::kBackgroundId;
                     }
             }});
}

TEST(ExtremeInputs, ZeroLengthNanAndHugeNormals) {
    runCase({"normals", [](int64_t frame, Frame& f) {
                 for (int y = 0; y < 32; ++y)
                     for (int x = 0; x < 48; ++x) {
                         const int k = (x * 7 + y * 3 + int(frame)) % 11;
                         if (k == 0) setRgb(f, "normal", x, y, 0.f, 0.f, 0.f);
                         if (k == 1) setRgb(f, "normal", x, y, kNaN, kNaN, kNaN);
                         if (k == 2) setRgb(f, "normal", x, y, kInf, -kInf, 0.f);
                         if (k == 3) setRgb(f, "normal", x, y, 0.f, 0.f, 1e3f);
                         if (k == 4) setRgb(f, "normal", x, y, 0.f, 0.f, -1.f);
                     }
             }});
}

TEST(ExtremeInputs, DepthFrom1eMinus4To1e6) {
    // Depth spans ten decades across the image (exponential in x), plus NaN/negative pixels.
    runCase({"depthrange", [](int64_t, Frame& f) {
                 for (int y = 0; y < 32; ++y)
                     for (int x = 0; x < 48; ++x)
                         f["depth"].at(0, x, y) = 1e-4f * std::pow(10.f, 10.f * float(x) / 47.f);
                 f["depth"].at(0, 3, 3) = kNaN;
                 f["depth"].at(0, 4, 3) = -1.f;
                 f["depth"].at(0, 5, 3) = 0.f;
             }});
}

TEST(ExtremeInputs, ZeroDepthGradient) {
    runCase({"flatdepth", [](int64_t, Frame& f) {
                 for (int y = 0; y < 32; ++y)
                     for (int x = 0; x < 48; ++x) f["depth"].at(0, x, y) = 5.f;
             }});
}

TEST(ExtremeInputs, ConstantImageZeroVariance) {
    // Zero variance everywhere (constant radiance 0.5): the luminance weight divides by ~eps;
    // the constant must be a fixed point of every pass (measured: exact to float rounding).
    runCase({"constant",
             [](int64_t, Frame& f) {
                 for (int c = 0; c < 3; ++c)
                     std::fill(f["color"].channel(c), f["color"].channel(c) + 48 * 32, 0.5f);
             },
             0.5f, 0.5f});
}

TEST(ExtremeInputs, MotionFarOffScreenNanAndInf) {
    runCase({"motion", [](int64_t frame, Frame& f) {
                 for (int y = 0; y < 32; ++y)
                     for (int x = 0; x < 48; ++x) {
                         float* mx = &f["motion"].at(0, x, y);
                         float* my = &f["motion"].at(1, x, y);
                         switch ((x + y + int(frame)) % 6) {
                             case 0:
                                 *mx = 1e9f, *my = -1e9f;
                                 break;
                             case 1:
                                 *mx = kNaN, *my = 0.f;
                                 break;
                             case 2:
                                 *mx = kInf, *my = -kInf;
                                 break;
                             case 3:
                                 *mx = 3.f * 48.f, *my = 0.f;
                                 break;
                             case 4:
                                 *mx = -2.5e4f, *my = 4e4f;
                                 break;
                             default:
                                 *mx = 0.25f, *my = -0.25f;
                                 break;
                         }
                     }
             }});
}

TEST(ExtremeInputs, TinyAndOddSizes) {
    // 1x1, 1xN, Nx1 and odd sizes: every A-Trous step (up to 16) is larger than the image.
    for (Extent e : {Extent{1, 1}, Extent{1, 7}, Extent{7, 1}, Extent{3, 5}, Extent{47, 31}}) {
        SCOPED_TRACE(std::to_string(e.width) + "x" + std::to_string(e.height));
        runCase({"size" + std::to_string(e.width) + "x" + std::to_string(e.height), nullptr,
                 kPlainLo, kPlainHi, e});
    }
}

TEST(ExtremeInputs, SinglePixelFireflies1e6To1e30) {
    // One firefly per frame on frames 1-5 (1e6, 1e10, 1e20, 1e30, FLT_MAX), at different
    // pixels, then two clean frames. SVGF clamps a firefly against its neighbourhood before it
    // enters the history, so no frame's output leaves the ordinary range by more than the clamp
    // bound (mean + 3 sigma of the neighbours). The GAMES202 pipeline has no firefly clamp: the
    // bilateral colour weight keeps the firefly from spreading to its neighbours, and the
    // history clamp removes it the next frame.
    const float value[5] = {1e6f, 1e10f, 1e20f, 1e30f, std::numeric_limits<float>::max()};
    const int px[5] = {8, 16, 24, 40, 2}, py[5] = {8, 16, 8, 24, 2};
    auto modify = [&](int64_t frame, Frame& f) {
        if (frame >= 1 && frame <= 5) {
            const int k = int(frame - 1);
            setRgb(f, "color", px[k], py[k], value[k], value[k], value[k]);
        }
    };
    for (const char* graph : {"svgf", "jbf"}) {
        SCOPED_TRACE(graph);
        const std::string scenario = std::string("firefly-") + graph;
        setScenario(scenario, plainScene({48, 32}, modify));
        const bool svgf = std::string(graph) == "svgf";
        const TestGraph g = svgf ? svgfGraph(scenario) : jbfGraph(scenario);
        std::vector<std::vector<float>> perThreads;
        for (int threads : {1, 2}) {
            RunOptions o;
            o.frames = 7;
            o.threads = threads;
            o.onFrame = [&](int64_t frame, const kestrel::ImageView& out) {
                float maxOther = 0.f, maxAll = 0.f;
                for (int y = 0; y < out.height(); ++y)
                    for (int x = 0; x < out.width(); ++x)
                        for (int c = 0; c < 3; ++c) {
                            const float v = out.at(c, x, y);
                            ASSERT_TRUE(std::isfinite(v)) << "frame " << frame;
                            maxAll = std::max(maxAll, v);
                            const bool isFirefly =
                                frame <= 5 && x == px[frame - 1] && y == py[frame - 1];
                            if (!isFirefly) maxOther = std::max(maxOther, v);
                        }
                const float bound = 2.f * kPlainHi;
                EXPECT_LE(maxOther, bound) << "frame " << frame << ": the firefly spread";
                if (svgf || frame > 5) {
                    EXPECT_LE(maxAll, bound) << "frame " << frame << ": firefly not clamped";
                }
            };
            perThreads.push_back(run(g, o));
        }
        EXPECT_TRUE(bitwiseEqual(perThreads[0], perThreads[1])) << "1 vs 2 threads differ";
    }
}

}  // namespace
}  // namespace stability
