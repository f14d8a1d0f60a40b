#include "eval/Regions.h"

#include <kestrel/Compiler.h>
#include <kestrel/Conventions.h>
#include <kestrel/Error.h>
#include <kestrel/Executor.h>
#include <kestrel/FramePattern.h>
#include <kestrel/Parallel.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "eval/ExrRgb.h"

namespace kestrel::eval {

const char* regionName(int region) {
    static const char* names[kRegionCount] = {"all",      "background",  "emissive", "glossy",
                                              "textured", "disoccluded", "flat",     "reflection"};
    return region >= 0 && region < kRegionCount ? names[region] : "?";
}

namespace {

float lum(float r, float g, float b) {
    return 0.2126f * r + 0.7152f * g + 0.0722f * b;
}

bool isBackground(const GBuffer& g, size_t i) {
    if (!g.depth.empty()) return !(g.depth[i] < 0.1f * kBackgroundDepth);  // NaN: background
    return !g.objectId.empty() && g.objectId[i] == kBackgroundId;
}

bool textured(const GBuffer& g, int x, int y) {
    const size_t i = size_t(y) * size_t(g.width) + size_t(x);
    float lo = g.albedoLum[i], hi = lo;
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if (xx < 0 || yy < 0 || xx >= g.width || yy >= g.height) continue;
            const size_t j = size_t(yy) * size_t(g.width) + size_t(xx);
            if (!g.objectId.empty() && g.objectId[j] != g.objectId[i]) continue;
            if (isBackground(g, j)) continue;
            lo = std::min(lo, g.albedoLum[j]);
            hi = std::max(hi, g.albedoLum[j]);
        }
    return hi > 1e-3f && hi - lo > 0.25f * hi;
}

/// Whether some tap of the bilinear footprint at p + motion in the previous frame shows the same
/// surface (same id, depth within 10%).
bool seenBefore(const GBuffer& cur, const GBuffer& prev, int x, int y) {
    const size_t i = size_t(y) * size_t(cur.width) + size_t(x);
    const float px = float(x) + 0.5f + cur.motionX[i], py = float(y) + 0.5f + cur.motionY[i];
    if (!std::isfinite(px) || !std::isfinite(py)) return false;
    const int x0 = int(std::floor(px - 0.5f)), y0 = int(std::floor(py - 0.5f));
    for (int dy = 0; dy <= 1; ++dy)
        for (int dx = 0; dx <= 1; ++dx) {
            const int xx = x0 + dx, yy = y0 + dy;
            if (xx < 0 || yy < 0 || xx >= prev.width || yy >= prev.height) continue;
            const size_t j = size_t(yy) * size_t(prev.width) + size_t(xx);
            if (!cur.objectId.empty() && !prev.objectId.empty() &&
                prev.objectId[j] != cur.objectId[i])
                continue;
            if (!cur.depth.empty() && !prev.depth.empty() &&
                !(std::fabs(prev.depth[j] - cur.depth[i]) <= 0.1f * cur.depth[i]))
                continue;
            return true;
        }
    return false;
}

}  // namespace

bool flatAround(const GBuffer& g, int x, int y) {
    if (x < 1 || y < 1 || x + 1 >= g.width || y + 1 >= g.height || g.albedoLum.empty())
        return false;
    const size_t i = size_t(y) * size_t(g.width) + size_t(x);
    const float a = g.albedoLum[i];
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            const size_t j = size_t(y + dy) * size_t(g.width) + size_t(x + dx);
            if (isBackground(g, j)) return false;
            if (!g.objectId.empty() && g.objectId[j] != g.objectId[i]) return false;
            if (!g.specularLum.empty() && !(g.specularLum[j] <= 0.02f)) return false;
            if (!g.emissionLum.empty() && !(g.emissionLum[j] <= 1e-3f)) return false;
            if (!(std::fabs(g.albedoLum[j] - a) <= 0.01f * (a + 0.01f))) return false;
        }
    if (g.depth.empty()) return true;
    // One plane: inverse depth is linear in screen space on a plane, so a crease (two walls of one
    // object) bends it along some line through the centre.
    const auto inv = [&](int dx, int dy) {
        return 1.0f / g.depth[size_t(y + dy) * size_t(g.width) + size_t(x + dx)];
    };
    const float c = inv(0, 0);
    for (auto [dx, dy] : {std::pair{1, 0}, {0, 1}, {1, 1}, {1, -1}})
        if (!(std::fabs(inv(dx, dy) + inv(-dx, -dy) - 2 * c) <= 0.01f * c)) return false;
    return true;
}

RegionMasks classifyRegions(const GBuffer& g, const GBuffer* prev) {
    const size_t n = size_t(g.width) * size_t(g.height);
    RegionMasks m;
    for (auto& v : m) v.assign(n, 0);
    const bool samePrev = prev && prev->width == g.width && prev->height == g.height;
    const bool disocc = samePrev && !g.motionX.empty();
    for (int y = 0; y < g.height; ++y)
        for (int x = 0; x < g.width; ++x) {
            const size_t i = size_t(y) * size_t(g.width) + size_t(x);
            m[kAll][i] = 1;
            if (isBackground(g, i)) {
                m[kBackground][i] = 1;
                continue;
            }
            const bool emissive = !g.emissionLum.empty() && g.emissionLum[i] > 1e-3f;
            m[kEmissive][i] = emissive;
            m[kGlossy][i] =
                !g.specularLum.empty() && !g.albedoLum.empty() && g.specularLum[i] > g.albedoLum[i];
            m[kTextured][i] = !emissive && !g.albedoLum.empty() && textured(g, x, y);
            m[kDisoccluded][i] = disocc && !seenBefore(g, *prev, x, y);
            m[kFlat][i] = !m[kTextured][i] && !m[kDisoccluded][i] && flatAround(g, x, y) &&
                          (!samePrev || flatAround(*prev, x, y));
            m[kReflection][i] = !g.reflection.empty() && g.reflection[i] > 0.5f;
        }
    return m;
}

struct GBufferReader::Impl {
    std::unique_ptr<CompiledGraph> graph;
    std::unique_ptr<Parallel> parallel;
    std::unique_ptr<Executor> exec;
    std::vector<std::string> provided;
    bool antiAliased = false;
};

namespace {

GraphDesc loaderGraph(const std::string& pattern, const std::vector<std::string>& outputs) {
    GraphDesc g;
    g.name = "regions";
    PassNode loader;
    loader.name = "input";
    loader.type = "ExrLoader";
    loader.paramsJson = nlohmann::json{{"path", pattern}}.dump();
    g.passes.push_back(loader);
    for (const auto& o : outputs) g.outputs.push_back("input." + o);
    return g;
}

std::vector<float> luminance(const ImageView& v) {
    std::vector<float> l(v.pixels());
    const float *r = v.channel(0), *g = v.channel(1), *b = v.channel(2);
    for (size_t i = 0; i < l.size(); ++i) l[i] = lum(r[i], g[i], b[i]);
    return l;
}

std::vector<float> plane(const ImageView& v, int c) {
    return {v.channel(c), v.channel(c) + v.pixels()};
}

}  // namespace

GBufferReader::GBufferReader(const Registry& registry, const std::string& pattern,
                             int64_t firstFrame)
    : impl_(std::make_unique<Impl>()) {
    CompileOptions copt;
    copt.firstFrame = firstFrame;
    // First compile: which outputs the scene has (absent ones are listed in the report).
    auto probe = compileGraph(loaderGraph(pattern, {"color"}), registry, copt);
    const auto provides = [&](const char* output) {
        for (const auto& a : probe->report().absent)
            if (a.rfind(std::string("input.") + output + ":", 0) == 0) return false;
        return true;
    };
    std::vector<std::string> want;
    for (const char* o :
         {"depth", "objectId", "emission", "albedo", "diffuseAlbedo", "specularAlbedo", "motion",
          "reflection"})
        if (provides(o)) want.push_back(o);
    impl_->provided = want;
    impl_->antiAliased = provides("jitteredAlbedo") || provides("jitteredDiffuseAlbedo");
    want.insert(want.begin(), "color");
    impl_->graph = compileGraph(loaderGraph(pattern, want), registry, copt);
    impl_->parallel = std::make_unique<Parallel>(0);
    impl_->exec = std::make_unique<Executor>(*impl_->graph, *impl_->parallel);
    impl_->exec->beginRun(firstFrame, firstFrame);
}

GBufferReader::~GBufferReader() = default;

const std::vector<std::string>& GBufferReader::provided() const {
    return impl_->provided;
}

bool GBufferReader::antiAliased() const {
    return impl_->antiAliased;
}

GBuffer GBufferReader::read(int64_t frame) {
    Executor& e = *impl_->exec;
    e.runFrame(frame, false);
    GBuffer g;
    const ImageView color = e.output("input.color");
    g.width = color.width();
    g.height = color.height();
    g.color = Image(color.extent, Format::Float3);
    for (int c = 0; c < 3; ++c)
        std::copy(color.channel(c), color.channel(c) + color.pixels(), g.color.view().channel(c));
    auto has = [&](const char* o) {
        return std::find(impl_->provided.begin(), impl_->provided.end(), o) !=
               impl_->provided.end();
    };
    if (has("depth")) g.depth = plane(e.output("input.depth"), 0);
    if (has("objectId")) {
        const ImageView v = e.output("input.objectId");
        g.objectId.assign(v.ints(), v.ints() + v.pixels());
    }
    if (has("emission")) g.emissionLum = luminance(e.output("input.emission"));
    // The diffuse albedo where the scene splits it (Blender's DiffCol), else the single one.
    if (has("diffuseAlbedo"))
        g.albedoLum = luminance(e.output("input.diffuseAlbedo"));
    else if (has("albedo"))
        g.albedoLum = luminance(e.output("input.albedo"));
    if (has("specularAlbedo")) g.specularLum = luminance(e.output("input.specularAlbedo"));
    if (has("reflection")) g.reflection = plane(e.output("input.reflection"), 0);
    if (has("motion")) {
        const ImageView v = e.output("input.motion");
        g.motionX = plane(v, 0);
        g.motionY = plane(v, 1);
    }
    return g;
}

DisplayFrame RegionStats::add(const ImageView& out, const ImageView& ref, const ImageView& input,
                              const RegionMasks& masks, ToneMap t, const DisplayFrame* previous) {
    const Image linearOut = sanitizedRgb(out), linearRef = sanitizedRgb(ref);
    Image o = toneMapped(linearOut.view(), t);
    Image r = toneMapped(linearRef.view(), t);
    const Image in = toneMapped(sanitizedRgb(input).view(), t);
    const size_t n = out.pixels();
    if (ref.pixels() != n || input.pixels() != n || masks[kAll].size() != n)
        throw Error("regions: output, reference, input and G-buffer differ in size");
    std::array<bool, kRegionCount> seen{};
    for (int c = 0; c < 3; ++c) {
        const float *po = o.view().channel(c), *pr = r.view().channel(c),
                    *pi = in.view().channel(c);
        for (size_t i = 0; i < n; ++i) {
            const double eo = double(po[i]) - pr[i], ei = double(pi[i]) - pr[i];
            for (int k = 0; k < kRegionCount; ++k)
                if (masks[size_t(k)][i]) {
                    outSse[size_t(k)] += eo * eo;
                    inSse[size_t(k)] += ei * ei;
                    ++samples[size_t(k)];
                    seen[size_t(k)] = true;
                }
        }
    }
    for (int k = 0; k < kRegionCount; ++k) framesWith[size_t(k)] += seen[size_t(k)];
    const std::vector<uint8_t> speckle = speckleMask(linearOut.view(), linearRef.view());
    for (size_t i = 0; i < n; ++i)
        if (speckle[i])
            for (int k = 0; k < kRegionCount; ++k) speckleCount[size_t(k)] += masks[size_t(k)][i];
    const auto sameSize = [&](const Image& a) {
        return a.width() == o.width() && a.height() == o.height();
    };
    if (previous && sameSize(previous->out) && sameSize(previous->ref))
        for (int c = 0; c < 3; ++c) {
            const float *po = o.view().channel(c), *pr = r.view().channel(c),
                        *qo = previous->out.view().channel(c),
                        *qr = previous->ref.view().channel(c);
            for (size_t i = 0; i < n; ++i) {
                const double e = temporalError(po[i], qo[i], pr[i], qr[i]);
                for (int k = 0; k < kRegionCount; ++k)
                    if (masks[size_t(k)][i]) {
                        temporalSum[size_t(k)] += e;
                        ++temporalSamples[size_t(k)];
                    }
            }
        }
    return {std::move(o), std::move(r)};
}

double RegionStats::speckles(int region) const {
    const uint64_t pixels = samples[size_t(region)] / 3;  // samples are pixel-channels
    return pixels ? 1e6 * double(speckleCount[size_t(region)]) / double(pixels) : 0.0;
}

namespace {
double psnrOf(double sse, uint64_t n) {
    const double mse = n ? std::max(sse / double(n), 1e-10) : 1e-10;
    return 10.0 * std::log10(1.0 / mse);
}
}  // namespace

double RegionStats::outPsnr(int k) const {
    return psnrOf(outSse[size_t(k)], samples[size_t(k)]);
}
double RegionStats::inPsnr(int k) const {
    return psnrOf(inSse[size_t(k)], samples[size_t(k)]);
}
double RegionStats::ratio(int k) const {
    // Both floored like PSNR: two near-perfect regions compare as equal, not as 0/0.
    const double n = double(std::max<uint64_t>(samples[size_t(k)], 1));
    return std::max(outSse[size_t(k)] / n, 1e-10) / std::max(inSse[size_t(k)] / n, 1e-10);
}

double RegionStats::temporal(int k) const {
    return temporalSum[size_t(k)] / double(std::max<uint64_t>(temporalSamples[size_t(k)], 1));
}

double RegionStats::referenceNoiseShare() const {
    return double(noise.samples) / double(std::max<uint64_t>(temporalSamples[kAll], 1));
}

bool RegionStats::worseThanInput(int k) const {
    const double n = double(std::max<uint64_t>(samples[size_t(k)], 1));
    return outSse[size_t(k)] / n > inSse[size_t(k)] / n + kMseSlack;
}

RegionStats compareRegions(const Registry& registry, const std::string& outPattern,
                           const std::string& refPattern, const std::string& inputPattern,
                           const std::vector<int64_t>& frames, ToneMap toneMap) {
    if (frames.empty()) throw Error("regions: no frames to compare");
    GBufferReader reader(registry, inputPattern, frames.front());
    RegionStats stats;
    GBuffer prev;
    DisplayFrame prevDisplay;
    bool havePrev = false;
    int64_t last = 0;
    for (int64_t f : frames) {
        GBuffer g = reader.read(f);
        // Disocclusion is judged against the frame just before, when the list has it.
        const bool consecutive = havePrev && f == last + 1;
        RegionMasks masks = classifyRegions(g, consecutive ? &prev : nullptr);
        const Image out = readExrRgb(expandFramePattern(outPattern, f));
        const Image ref = readExrRgb(expandFramePattern(refPattern, f));
        DisplayFrame shown = stats.add(out.view(), ref.view(), g.color.view(), masks, toneMap,
                                       consecutive ? &prevDisplay : nullptr);
        // Not on anti-aliased renders: the reference's noise is correlated between neighbours.
        if (consecutive && !reader.antiAliased())
            stats.noise.add(shown, prevDisplay, g, prev, masks[kFlat]);
        prevDisplay = std::move(shown);
        prev = std::move(g);
        havePrev = true;
        last = f;
    }
    return stats;
}

std::string formatRegionTable(const RegionStats& s) {
    std::string t =
        "region         share   input dB  output dB   out/in MSE   temporal  speckles/Mpx\n";
    const double all = double(std::max<uint64_t>(s.samples[kAll], 1));
    char line[256], temporal[32];
    for (int k = 0; k < kRegionCount; ++k) {
        if (!s.has(k)) continue;
        if (s.hasTemporal(k))
            std::snprintf(temporal, sizeof temporal, "%10.5f", s.temporal(k));
        else
            std::snprintf(temporal, sizeof temporal, "%10s", "-");
        std::snprintf(line, sizeof line, "%-12s %6.1f%%  %9.2f  %9.2f   %10.3f %s  %12.0f%s\n",
                      regionName(k), 100.0 * double(s.samples[size_t(k)]) / all, s.inPsnr(k),
                      s.outPsnr(k), s.ratio(k), temporal, s.speckles(k),
                      s.worseThanInput(k) ? "  worse than the input" : "");
        t += line;
    }
    if (s.reportsReferenceNoise()) {
        std::snprintf(line, sizeof line,
                      "reference's own noise, estimated on %.1f%% of the frame (flat): %.5f, about "
                      "the least temporal instability there; this output's %.5f (%.2fx)\n",
                      100.0 * s.referenceNoiseShare(), s.noise.floor(), s.noise.output(),
                      s.noise.output() / std::max(s.noise.floor(), 1e-12));
        t += line;
    }
    return t;
}

nlohmann::json regionsToJson(const RegionStats& s) {
    nlohmann::json j = nlohmann::json::object();
    for (int k = 0; k < kRegionCount; ++k) {
        if (!s.has(k)) continue;
        j[regionName(k)] = {{"share", double(s.samples[size_t(k)]) /
                                          double(std::max<uint64_t>(s.samples[kAll], 1))},
                            {"inputPsnr", s.inPsnr(k)},
                            {"outputPsnr", s.outPsnr(k)},
                            {"mseRatio", s.ratio(k)},
                            {"worseThanInput", s.worseThanInput(k)},
                            {"speckles", s.speckles(k)},
                            {"frames", s.framesWith[size_t(k)]}};
        if (s.hasTemporal(k)) j[regionName(k)]["temporal"] = s.temporal(k);
    }
    if (s.reportsReferenceNoise())
        j["referenceNoise"] = {{"share", s.referenceNoiseShare()},
                               {"floor", s.noise.floor()},
                               {"output", s.noise.output()}};
    return j;
}

}  // namespace kestrel::eval
