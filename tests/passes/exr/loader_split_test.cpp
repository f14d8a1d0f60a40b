// The Blender diffuse/specular split loses no light: Combined may hold light that no enabled
// pass does (glass without the Transmission passes, fog without the Volume passes), or less than
// the passes (a transparent film's sky is in Env, not in Combined). The loader gives the rest to
// specular (filtered) or emission (kept as it was), so diffuse + specular + emission = Combined
// on every pixel and no graph drops or adds light.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "ExrLoader.h"
#include "exr_test_util.h"
#include "kestrel/testing/PassHarness.h"

using kestrel::exr::ExrLoader;
using kestrel::testing::PassHarness;
using namespace exrtest;

namespace {

/// A 4x1 Blender frame, grey per pass (one value per pixel, the same in R, G and B):
///   pixel 0: an opaque surface (diffuse, glossy and a little emission),
///   pixel 1: glass rendered without the Transmission passes (0.4 in Combined only),
///   pixel 2: a transparent film's sky (Env 0.7, Combined 0, no surface),
///   pixel 3: an anti-aliased edge of a surface against that sky (Env 0.35, Combined only the
///            surface's 0.2).
Channels fourPixels() {
    Channels ch;
    auto grey = [&](const std::string& pass, std::vector<float> v) {
        for (const char* c : {"R", "G", "B"}) ch["ViewLayer." + pass + "." + c] = v;
    };
    grey("DiffDir", {0.3f, 0.f, 0.f, 0.2f});
    grey("DiffInd", {0.1f, 0.f, 0.f, 0.f});
    grey("DiffCol", {0.5f, 0.f, 0.f, 0.5f});
    grey("GlossDir", {0.2f, 0.1f, 0.f, 0.1f});
    grey("GlossInd", {0.f, 0.1f, 0.f, 0.f});
    grey("GlossCol", {1.f, 0.8f, 0.f, 1.f});
    grey("Emit", {0.05f, 0.f, 0.f, 0.f});
    grey("Env", {0.f, 0.f, 0.7f, 0.35f});
    // Combined = 0.4*0.5 + 0.2*1 + 0.05; 0.2*0.8 + 0.4; 0 (transparent); 0.1 + 0.1.
    grey("Combined", {0.45f, 0.56f, 0.f, 0.2f});
    ch["ViewLayer.Combined.A"] = {1.f, 1.f, 0.f, 0.5f};
    return ch;
}

constexpr int kPixels = 4;

/// The loader on `ch` (frame 1), computing `outputs`; `channels`: the channels parameter.
PassHarness loadFrame(const TempDir& tmp, const Channels& ch, const std::string& channels = {},
                      const std::vector<std::string>& outputs = {"color", "diffuse", "specular",
                                                                 "specularAlbedo", "emission"}) {
    writeExr(tmp.path / "f.0001.exr", Imath::Box2i({0, 0}, {kPixels - 1, 0}), ch);
    std::map<std::string, kestrel::ParamValue> params = {
        {"path", (tmp.path / "f.####.exr").string()}};
    if (!channels.empty()) params["channels"] = channels;
    auto h = PassHarness::make<ExrLoader>({1, 1}, params);
    h.useOutputs(outputs);
    h.ctx.frameNumber = 1;
    h.run();
    return h;
}

void expectSplitSumsToCombined(PassHarness& h) {
    for (int x = 0; x < kPixels; ++x)
        for (int c = 0; c < 3; ++c) {
            const float sum = h.out("diffuse").at(c, x, 0) + h.out("specular").at(c, x, 0) +
                              h.out("emission").at(c, x, 0);
            EXPECT_NEAR(sum, h.out("color").at(c, x, 0), 1e-6f)
                << "pixel " << x << " channel " << c;
        }
}

}  // namespace

TEST(ExrLoaderSplit, LightNoPassHoldsIsFilteredAsSpecular) {
    TempDir tmp("split-rest");
    auto h = loadFrame(tmp, fourPixels());
    expectSplitSumsToCombined(h);
    EXPECT_NEAR(h.out("specular").at(0, 0, 0), 0.2f, 1e-6f);          // glossy only
    EXPECT_NEAR(h.out("emission").at(0, 0, 0), 0.05f, 1e-6f);         // Emit
    EXPECT_NEAR(h.out("specular").at(0, 1, 0), 0.16f + 0.4f, 1e-6f);  // glossy + the glass
    EXPECT_NEAR(h.out("emission").at(0, 1, 0), 0.f, 1e-6f);
    EXPECT_NEAR(h.out("specular").at(0, 2, 0), 0.f, 1e-6f);  // never negative light to filter
    EXPECT_NEAR(h.out("emission").at(0, 2, 0), 0.f, 1e-6f);  // Env less what Combined lacks
    EXPECT_NEAR(h.out("specular").at(0, 3, 0), 0.1f, 1e-6f);
    EXPECT_NEAR(h.out("emission").at(0, 3, 0), 0.f, 1e-6f);  // the edge's surface is all of it
}

// A graph that binds specular without diffuse computes the rest from the passes themselves
// (svgf.json binds both and takes it from their planes): the same specular.
TEST(ExrLoaderSplit, RestFromThePassesMatchesTheRestFromThePlanes) {
    TempDir tmp("split-rest-generic");
    auto h = loadFrame(tmp, fourPixels(), {}, {"specular", "emission"});
    TempDir tmp2("split-rest-planes");
    auto all = loadFrame(tmp2, fourPixels());
    for (int x = 0; x < kPixels; ++x)
        EXPECT_NEAR(h.out("specular").at(0, x, 0), all.out("specular").at(0, x, 0), 1e-6f) << x;
}

// Non-finite passes add no light to the rest (demodulation would zero the whole pixel's
// specular light).
TEST(ExrLoaderSplit, NonFinitePassesAddNoRest) {
    TempDir tmp("split-nonfinite");
    Channels ch = fourPixels();
    for (const char* c : {"R", "G", "B"}) {
        ch[std::string("ViewLayer.Emit.") + c][0] = NAN;
        ch[std::string("ViewLayer.DiffInd.") + c][1] = INFINITY;
        ch[std::string("ViewLayer.Combined.") + c][3] = INFINITY;
    }
    auto h = loadFrame(tmp, ch);
    EXPECT_NEAR(h.out("specular").at(0, 0, 0), 0.2f, 1e-6f);
    EXPECT_NEAR(h.out("specular").at(0, 1, 0), 0.16f, 1e-6f);
    EXPECT_NEAR(h.out("specular").at(0, 3, 0), 0.1f, 1e-6f);
}

TEST(ExrLoaderSplit, TransmissionPassesJoinTheSpecularChain) {
    TempDir tmp("split-trans");
    Channels ch = fourPixels();
    for (const char* c : {"R", "G", "B"}) {
        ch[std::string("ViewLayer.TransDir.") + c] = {0.f, 0.3f, 0.f, 0.f};
        ch[std::string("ViewLayer.TransInd.") + c] = {0.f, 0.2f, 0.f, 0.f};
        ch[std::string("ViewLayer.TransCol.") + c] = {0.f, 0.8f, 0.f, 0.f};
    }
    auto h = loadFrame(tmp, ch);
    expectSplitSumsToCombined(h);
    EXPECT_NE(static_cast<ExrLoader&>(h.pass())
                  .plan()
                  .find("specular")
                  ->why.find("ViewLayer.TransDir*ViewLayer.TransCol"),
              std::string::npos);
    EXPECT_NEAR(h.out("specular").at(0, 1, 0), 0.16f + 0.4f, 1e-6f);
    // Demodulated by both colours: (0.2*0.8 + 0.5*0.8) / (0.8 + 0.8) is the glass's lighting.
    EXPECT_NEAR(h.out("specularAlbedo").at(0, 1, 0), 1.6f, 1e-6f);
    EXPECT_NEAR(h.out("specularAlbedo").at(0, 0, 0), 1.f, 1e-6f);
}

TEST(ExrLoaderSplit, ChannelsParameterKeepsTheSumWhole) {
    TempDir tmp("split-override");
    // Only the direct glossy light filtered as specular, as the user chose: the indirect and
    // the glass are added back unfiltered.
    auto h = loadFrame(tmp, fourPixels(), "specular=ViewLayer.GlossDir*ViewLayer.GlossCol");
    expectSplitSumsToCombined(h);
    EXPECT_NEAR(h.out("specular").at(0, 1, 0), 0.08f, 1e-6f);
    EXPECT_NEAR(h.out("emission").at(0, 1, 0), 0.08f + 0.4f, 1e-6f);
}

// The channels parameter's colour is what the emission is capped by, not Combined.
TEST(ExrLoaderSplit, ChannelsParameterColourCapsTheEmission) {
    TempDir tmp("split-color-override");
    Channels ch = fourPixels();
    for (const char* c : {"R", "G", "B"})
        ch[std::string("ViewLayer.Alt.") + c] = {0.45f, 0.56f, 0.3f, 0.2f};  // pixel 2: 0.3
    auto h = loadFrame(tmp, ch, "color=ViewLayer.Alt");
    expectSplitSumsToCombined(h);
    EXPECT_NEAR(h.out("emission").at(0, 2, 0), 0.3f, 1e-6f);
}

// Diffuse and Glossy passes without Emission and Environment: the sky and the emitters are in
// Combined only, and svgf.json added nothing back for them: the sky came out black
// (blender-street without Emit and Env: 8.18 dB against 15.18 at 1 spp). They now join the
// specular light, filtered as radiance where GlossCol is 0.
TEST(ExrLoaderSplit, SplitWithoutEmitOrEnvKeepsTheSky) {
    TempDir tmp("split-no-emit");
    Channels ch = fourPixels();
    for (const char* c : {"R", "G", "B"}) {
        ch.erase(std::string("ViewLayer.Emit.") + c);
        ch.erase(std::string("ViewLayer.Env.") + c);
        ch[std::string("ViewLayer.Combined.") + c] = {0.45f, 0.56f, 0.7f, 0.55f};  // 2, 3: sky
    }
    auto h = loadFrame(tmp, ch);
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    EXPECT_EQ(rc.absent.count("emission"), 1u);  // the harness gives 0 for it
    expectSplitSumsToCombined(h);
    EXPECT_NEAR(h.out("specular").at(0, 2, 0), 0.7f, 1e-6f);   // filtered as radiance
    EXPECT_NEAR(h.out("specular").at(0, 0, 0), 0.25f, 1e-6f);  // glossy + the emitter
}

// A graph that filters the colour without the split (games202-jbf: colour minus emission) reads
// Combined, Emit and Env only: the emission's cap needs no split pass.
TEST(ExrLoaderSplit, EmissionAloneReadsNoSplitPass) {
    TempDir tmp("split-emission-only");
    auto h = loadFrame(tmp, fourPixels(), {}, {"color", "emission"});
    EXPECT_NEAR(h.out("emission").at(0, 0, 0), 0.05f, 1e-6f);
    EXPECT_NEAR(h.out("emission").at(0, 2, 0), 0.f, 1e-6f);  // min(Env, Combined)
    const auto read = static_cast<ExrLoader&>(h.pass()).channelsRead();
    EXPECT_EQ(read.size(), 9u);  // Combined, Emit, Env
    for (const auto& c : read) EXPECT_EQ(c.find("Diff"), std::string::npos) << c;
    for (const auto& c : read) EXPECT_EQ(c.find("Gloss"), std::string::npos) << c;
}

// Kestrel's own layout with the split but without the emission AOV (a renderer that writes
// diffuse and specular only, `kestrel scenegen --omit emission`): its contract is color ==
// diffuse + specular + emission, so the emission is the rest of the colour, added back
// unfiltered. The graphs added nothing back for it: the zoo street's sky came out black
// (11.15 dB against 19.39 at 1 spp; 26.12 now, as with the emission AOV).
namespace {
/// Canonical channels, grey per AOV: pixel 0 a surface with an emitter, 1 a plain surface, 2 the
/// sky, 3 a pixel a filter's negative lobe made negative.
Channels canonicalSplitWithoutEmission() {
    Channels ch;
    auto grey = [&](const std::string& layer, std::vector<float> v) {
        for (const char* c : {"R", "G", "B"}) ch[layer.empty() ? c : layer + "." + c] = v;
    };
    grey("diffuse", {0.2f, 0.3f, 0.f, 0.05f});
    grey("specular", {0.1f, 0.f, 0.f, 0.f});
    grey("", {0.5f, 0.3f, 0.7f, -0.1f});
    grey("alt", {0.6f, 0.3f, 0.7f, 0.05f});
    return ch;
}
}  // namespace

TEST(ExrLoaderSplit, CanonicalSplitWithoutEmissionKeepsTheSky) {
    TempDir tmp("split-canonical-no-emission");
    auto h = loadFrame(tmp, canonicalSplitWithoutEmission());
    expectSplitSumsToCombined(h);
    EXPECT_NEAR(h.out("emission").at(0, 0, 0), 0.2f, 1e-6f);
    EXPECT_NEAR(h.out("emission").at(0, 1, 0), 0.f, 1e-6f);
    EXPECT_NEAR(h.out("emission").at(0, 2, 0), 0.7f, 1e-6f);  // the sky, never filtered
    EXPECT_NEAR(h.out("specular").at(0, 2, 0), 0.f, 1e-6f);
    EXPECT_NEAR(h.out("emission").at(0, 3, 0), -0.15f, 1e-6f);
}

// The channels parameter's colour is what the derived emission completes.
TEST(ExrLoaderSplit, CanonicalDerivedEmissionFollowsTheChannelsParameter) {
    TempDir tmp("split-canonical-override");
    auto h = loadFrame(tmp, canonicalSplitWithoutEmission(), "color=alt");
    expectSplitSumsToCombined(h);
    EXPECT_NEAR(h.out("emission").at(0, 0, 0), 0.3f, 1e-6f);
}
