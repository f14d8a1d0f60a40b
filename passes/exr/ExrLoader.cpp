#include "ExrLoader.h"

#include <OpenEXR/ImfAttribute.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfThreading.h>
#include <kestrel/PixelMath.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <set>

#include "Absurd.h"
#include "KeepPasses.h"
#include "PixelJitter.h"
#include "Unproject.h"

namespace kestrel::exr {

namespace fs = std::filesystem;

namespace {
const char* const kGames202Roles[] = {"beauty", "normal", "position", "depth", "ID"};

std::string parentDir(const std::string& p) {
    auto slash = p.rfind('/');
    return slash == std::string::npos ? std::string() : p.substr(0, slash + 1);
}

std::set<std::string> channelNames(const Imf::Header& h) {
    std::set<std::string> names;
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it) names.insert(it.name());
    return names;
}

Mat4 toMat4(const Imath::M44f& x) {
    Mat4 m;
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) m.m[r][c] = x[r][c];
    return m;
}

float* asFloats(const ImageView& v, int c) {
    return v.planes[size_t(c)];
}

void fillPlane(float* p, size_t n, float value) {
    std::fill(p, p + n, value);
}

/// Cycles' camera-space directions (x right, y up, z forward: measured on blender-street, where
/// the ground's Denoising Normal is (0, 0.989, 0.151) under a view whose up row is
/// (.., 0.989, -0.151)) to world space: z flipped to the OpenGL view's (looking down -z), then
/// by the transpose of the view's rotation (orthonormal for Blender's cameras). The
/// background's zero vectors stay zero.
void rotateToWorld(const Mat4& worldToCamera, const ImageView& v, size_t n) {
    const auto& m = worldToCamera.m;
    float *x = asFloats(v, 0), *y = asFloats(v, 1), *z = asFloats(v, 2);
    for (size_t i = 0; i < n; ++i) {
        const float cx = x[i], cy = y[i], cz = -z[i];
        x[i] = m[0][0] * cx + m[1][0] * cy + m[2][0] * cz;
        y[i] = m[0][1] * cx + m[1][1] * cy + m[2][1] * cz;
        z[i] = m[0][2] * cx + m[1][2] * cy + m[2][2] * cz;
    }
}

/// Object ids arrive as floats; stored in place as int32 (the plane's own memory).
void floatsToIds(float* plane, size_t n, IdRule rule) {
    for (size_t i = 0; i < n; ++i) {
        float v;
        std::memcpy(&v, plane + i, 4);
        int32_t id = kBackgroundId;
        if (rule == IdRule::BlenderZeroIsBackground) {
            if (v >= 0.5f && v < 2.1e9f) id = int32_t(std::lround(v));  // IndexOB: 0 = background
        } else if (v > -0.5f && v < 2.1e9f) {
            id = int32_t(std::lround(v));
        }
        std::memcpy(plane + i, &id, 4);
    }
}
/// Decodes `chans` of `in` into display-window planes (W x H of `dp`) on up to `threads`
/// threads; pixels outside the data window get the channel's fill value. ZIP/ZIPS scan-line
/// files take the fast path (ZipScanlines.h); the rest, and files it finds damaged, are read
/// by OpenEXR. Throws what OpenEXR throws.
void readChannels(ExrInput& in, const Box& dp, int W, size_t N,
                  const std::vector<std::pair<std::string, float*>>& chans,
                  const std::vector<float>& fillv, int threads, const Workspace& lent = {},
                  const std::vector<AbsurdFix>& fixes = {}) {
    const Box dw = in.dataWindow();
    const bool covers = dw.x0 <= dp.x0 && dw.y0 <= dp.y0 && dw.x1 >= dp.x1 && dw.y1 >= dp.y1;
    const bool inside = dw.x0 >= dp.x0 && dw.y0 >= dp.y0 && dw.x1 <= dp.x1 && dw.y1 <= dp.y1;
    if (!covers)
        for (size_t k = 0; k < chans.size(); ++k) fillPlane(chans[k].second, N, fillv[k]);
    const int ix0 = std::max(dw.x0, dp.x0), ix1 = std::min(dw.x1, dp.x1);
    const int iy0 = std::max(dw.y0, dp.y0), iy1 = std::min(dw.y1, dp.y1);
    if (ix0 > ix1 || iy0 > iy1) return;  // no overlap: fill values only
    if (const ZipScanlines* zip = in.zip()) {
        std::string why;
        if (zip->decode(dp, W, chans, fillv, threads, &why, nullptr, lent, fixes)) return;
        spdlog::debug("ExrLoader: {}: {}; reading it through OpenEXR", in.path(), why);
        for (const AbsurdFix& f : fixes)
            if (f.replaced) *f.replaced = 0;  // counted again below
    }
    Imf::FrameBuffer fb;
    std::vector<float> clip;  // only when the data window pokes out of the display
    const size_t dwW = size_t(dw.width()), rows = size_t(iy1 - iy0 + 1);
    if (!inside) clip.resize(dwW * rows * chans.size());
    for (size_t k = 0; k < chans.size(); ++k) {
        // Slice base: the address pixel (0, 0) would have (OpenEXR's convention).
        uintptr_t base;
        size_t yStride;
        if (inside) {
            int64_t origin = int64_t(dp.x0) + int64_t(dp.y0) * W;
            base = uintptr_t(chans[k].second) - uintptr_t(origin * 4);
            yStride = size_t(W) * 4;
        } else {
            float* buf = clip.data() + k * dwW * rows;
            int64_t origin = int64_t(dw.x0) + int64_t(iy0) * int64_t(dwW);
            base = uintptr_t(buf) - uintptr_t(origin * 4);
            yStride = dwW * 4;
        }
        fb.insert(chans[k].first, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(base), 4, yStride,
                                             1, 1, fillv[k]));
    }
    in.file().setFrameBuffer(fb);
    in.file().readPixels(iy0, iy1);
    if (!inside)
        for (size_t k = 0; k < chans.size(); ++k)
            for (int y = iy0; y <= iy1; ++y) {
                const float* src =
                    clip.data() + k * dwW * rows + size_t(y - iy0) * dwW + size_t(ix0 - dw.x0);
                float* dst = chans[k].second + size_t(y - dp.y0) * size_t(W) + size_t(ix0 - dp.x0);
                std::copy(src, src + (ix1 - ix0 + 1), dst);
            }
    // OpenEXR's path (other compressions, damaged files): a pass of its own over the planes.
    for (size_t k = 0; k < fixes.size(); ++k)
        if (fixes[k].on)
            *fixes[k].replaced += replaceAbsurd(chans[k].second, N, fixes[k].fill, fixes[k].lowest);
}
using Planes = std::map<ChannelRef, float*>;

/// out[i - b] += sign * the product of the term's factors (channel c of each), i in [b, e).
void addTerm(const Term& t, const Planes& dest, int c, float sign, float* __restrict out, size_t b,
             size_t e) {
    const float* __restrict f0 = dest.at(t[0][size_t(c)]) + b;
    const size_t n = e - b;
    if (t.size() == 1) {
        for (size_t i = 0; i < n; ++i) out[i] += sign * f0[i];
        return;
    }
    const float* __restrict f1 = dest.at(t[1][size_t(c)]) + b;
    if (t.size() == 2) {
        for (size_t i = 0; i < n; ++i) out[i] += sign * (f0[i] * f1[i]);
        return;
    }
    for (size_t i = 0; i < n; ++i) {
        float v = f0[i] * f1[i];
        for (size_t k = 2; k < t.size(); ++k) v *= dest.at(t[k][size_t(c)])[b + i];
        out[i] += sign * v;
    }
}

/// Pixels per block of the composites: every plane a block reads stays in the core's cache
/// from one recipe to the next (a 1080p Blender frame's ~30 planes: 1 MB per block), and each
/// term looks its planes up once per block.
constexpr size_t kCompositeBlock = 8192;
using Block = std::array<float, kCompositeBlock>;

/// out[i - b] = min(out[i - b], the sum of `cap`) (Recipe::cap), e - b <= kCompositeBlock.
void applyCap(const std::vector<Term>& cap, const Planes& dest, int c, float* out, size_t b,
              size_t e) {
    Block v;
    std::fill(v.begin(), v.begin() + (e - b), 0.f);
    for (const Term& t : cap) addTerm(t, dest, c, 1.f, v.data(), b, e);
    for (size_t i = 0; i < e - b; ++i) out[i] = std::min(out[i], v[i]);
}

/// The emission the split leaves unfiltered: at most the light the split passes leave, t =
/// color - diffuse - specular (an anti-aliased edge against a transparent film's sky has Env
/// but less Combined), so diffuse + specular + emission never exceeds color. t NaN or Inf (a
/// broken pass): the emission as it is.
inline float splitEmission(float e, float t) {
    return t < 0.f ? 0.f : (t < e ? t : e);
}

/// Light in `x` only where finite and positive (a NaN or Inf pass adds none).
inline float finitePositive(float x) {
    return x > 0.f && x <= std::numeric_limits<float>::max() ? x : 0.f;
}

/// Specular plus the positive part of the rest, from planes computed already (color, diffuse,
/// and emission, which is tightened in place by splitEmission; null: none): out = specular +
/// color - diffuse - specular - emission where that is positive. The same values as addRest's.
void addPositiveRest(const float* __restrict color, const float* __restrict diffuse,
                     float* __restrict emission, float* __restrict out, size_t n) {
    for (size_t i = 0; i < n; ++i) {
        const float t = color[i] - diffuse[i] - out[i];
        const float e = emission ? splitEmission(emission[i], t) : 0.f;
        if (emission) emission[i] = e;
        out[i] += finitePositive(t - e);
    }
}

/// out[i - b] += the part of the rest (Recipe::Rest) that `rest` names, e - b <=
/// kCompositeBlock: Positive, t - splitEmission(emission, t) where positive (t = color -
/// passes); Whole, t - min(emission, color), so emission + it = t. `withEmission` false: the
/// graph adds no emission back, so none is taken out.
void addRest(const Recipe::Rest& rest, const Planes& dest, int c, bool withEmission, float* out,
             size_t b, size_t e) {
    Block t, emission;
    const size_t n = e - b;
    for (Block* x : {&t, &emission}) std::fill(x->begin(), x->begin() + n, 0.f);
    for (const Term& term : rest.color) addTerm(term, dest, c, 1.f, t.data(), b, e);
    Block color = t;
    for (const Term& term : rest.passes) addTerm(term, dest, c, -1.f, t.data(), b, e);
    if (withEmission)
        for (const Term& term : rest.emission) addTerm(term, dest, c, 1.f, emission.data(), b, e);
    if (rest.part == Recipe::Rest::Part::Positive) {
        for (size_t i = 0; i < n; ++i)
            out[i] += finitePositive(t[i] - splitEmission(emission[i], t[i]));
        return;
    }
    // Without emission terms (a split without Emit/Env) none is taken: min(0, color) would take
    // a negative colour (a pixel filter's negative lobe) out twice.
    const bool anyEmission = withEmission && !rest.emission.empty();
    for (size_t i = 0; i < n; ++i) {
        const float r = t[i] - (anyEmission ? std::min(emission[i], color[i]) : 0.f);
        out[i] += std::isfinite(r) ? r : 0.f;
    }
}

}  // namespace

PassDesc ExrLoader::describe() {
    PassDesc d(
        "ExrLoader",
        "Reads AOV frames from EXR files (canonical, Blender multilayer or GAMES202 layout); "
        "only channels a consumer needs are decoded");
    for (const auto& o : loaderOutputs()) d.output(o.name, o.format, o.description);
    d.paramString("path", "",
                  "frame pattern (frame_####.exr, %04d, beauty_%d.exr) or a GAMES202 folder");
    d.paramEnum("layout", "auto", {"auto", "canonical", "blender", "games202"},
                "file layout; auto: kestrel.layout attribute, Blender channels, beauty_*.exr");
    d.paramString("layer", "",
                  "Blender view layer to read; empty: the only one (a file with several is "
                  "refused, naming them)");
    d.paramString("camera", "",
                  "Blender camera.json; empty: look beside the frames, then one folder up");
    d.paramString("channels", "",
                  "override output channels: out=Layer[*Layer][+...],... e.g. "
                  "albedo=ViewLayer.DiffCol (empty expression: leave the output out)");
    d.paramEnum(
        "antiAliased", "auto", {"auto", "true", "false"},
        "whether the render is anti-aliased (the jittered* albedos present); auto: the pixel "
        "filter camera.json or kestrel.pixelFilterWidth states, else the first frame's "
        "depth jitter");
    d.paramInt("maxPixels", int64_t(1) << 27, 1, int64_t(1) << 40,
               "largest data or display window accepted (pixels), checked before allocating; "
               "OpenEXR's per-chunk buffers are held to 16 bytes per maxPixels pixel");
    d.paramBool("prefetch", false,
                "decode the next frame on a background thread while the graph computes this "
                "one; costs a second set of the channels read (4 bytes per channel per pixel: "
                "about 160 MB, 76 B/px, for 19 channels at 1920x1080), so it is off by default "
                "(svgf.json's whole run stays under 256 B/px); pays off with a spare core");
    return d;
}

ExrLoader::ExrLoader(const ParamValues& p)
    : path_(p.getString("path")),
      layoutParam_(p.getString("layout")),
      cameraParam_(p.getString("camera")),
      channelsParam_(p.getString("channels")),
      antiAliasedParam_(p.getString("antiAliased")),
      layerParam_(p.getString("layer")),
      maxPixels_(p.getInt("maxPixels")),
      prefetch_(p.getBool("prefetch")) {}

ExrLoader::~ExrLoader() {
    cancel_ = true;
    joinPrefetch();
}

void ExrLoader::beginRun(const RunContext& rc) {
    cancel_ = true;
    joinPrefetch();
    pending_.reset();
    ready_.reset();
    lastFrame_ = rc.lastFrame >= rc.firstFrame ? rc.lastFrame : INT64_MAX;
    haveLast_ = false;
    step_ = 1;
    checkCameraFrames(rc.firstFrame);
}

std::string ExrLoader::cameraGap(const std::vector<int64_t>& frames) const {
    std::string list = std::to_string(frames.front());
    if (frames.size() > 1) list += " (and " + std::to_string(frames.size() - 1) + " more)";
    return "camera file " + cameras_->path().string() + " lists no frame " + list +
           " of the input: its positions, normals and motion would be computed without a "
           "camera; write it for every frame rendered (scripts/blender/kestrel_setup.py "
           "--camera-only --frames A-B, docs/blender.md)";
}

void ExrLoader::checkCameraFrames(int64_t firstFrame) const {
    // Before frame 1, not at the first frame without an entry, hours into a shot.
    if (plan_.layout != Layout::Blender || !cameras_) return;
    std::vector<int64_t> missing;
    for (int64_t f : availableFrames())
        if (f >= firstFrame && f <= lastFrame_ && !cameras_->has(f)) missing.push_back(f);
    if (!missing.empty()) throw Error(cameraGap(missing));
}

void ExrLoader::endRun() {
    cancel_ = true;
    joinPrefetch();
    pending_.reset();
    ready_.reset();
    spare_.clear();
}

void ExrLoader::joinPrefetch() {
    if (prefetchJob_.valid()) prefetchJob_.get();  // the job catches everything itself
}

void ExrLoader::startPrefetch(int64_t frame, const std::map<ChannelRef, float>& fills,
                              const std::map<ChannelRef, float>& direct) {
    joinPrefetch();  // execute without beginFrame (tests): never two read-aheads at once
    if (pending_) {
        spare_ = std::move(pending_->planes);
        pending_.reset();
    }
    if (frame > lastFrame_ || fills.empty()) return;
    const int W = int(display_.width());
    const size_t N = size_t(W) * size_t(display_.height());
    if (spareN_ != N) spare_.clear();  // planes of another frame size
    spareN_ = N;
    auto job = std::make_unique<Prefetch>();
    job->frame = frame;
    // Files in the order execute opens them: the primary first (its window is the frame's).
    std::string primary = plan_.layout == Layout::Games202 ? "beauty" : "";
    std::vector<std::string> roles{primary};
    std::vector<std::vector<std::pair<std::string, float*>>> chans(1);
    std::vector<std::vector<float>> fillv(1);
    std::vector<std::vector<AbsurdFix>> fixes(1);
    for (const auto& [ref, fill] : fills) {
        auto it = std::find(roles.begin(), roles.end(), ref.file);
        size_t k = size_t(it - roles.begin());
        if (it == roles.end()) {
            roles.push_back(ref.file);
            chans.emplace_back();
            fillv.emplace_back();
            fixes.emplace_back();
        }
        auto sp = spare_.find(ref);
        PlaneStorage plane = sp != spare_.end() ? std::move(sp->second) : allocatePlane(N);
        chans[k].emplace_back(ref.name, plane.get());
        fillv[k].push_back(fill);
        const auto d = direct.find(ref);
        fixes[k].push_back({d != direct.end(), fill, &job->replaced[ref],
                            d != direct.end() ? d->second : -kAbsurd});
        job->planes[ref] = std::move(plane);
    }
    spare_.clear();
    pending_ = std::move(job);
    cancel_ = false;
    Prefetch* P = pending_.get();
    const Box display = display_;
    prefetchJob_ =
        std::async(std::launch::async, [this, P, roles = std::move(roles), chans = std::move(chans),
                                        fillv = std::move(fillv), fixes = std::move(fixes), display,
                                        W, N, threads = threads_] {
            try {
                for (const auto& role : roles) {
                    if (cancel_) return;
                    auto in = std::make_unique<ExrInput>(filePath(role, P->frame), maxPixels_);
                    if (in->displayWindow() != display) return;  // read again, unprefetched
                    P->open.emplace_back(role, std::move(in));
                }
                for (size_t k = 0; k < roles.size(); ++k) {
                    if (cancel_) return;
                    if (!chans[k].empty())
                        readChannels(*P->open[k].second, display, W, N, chans[k], fillv[k], threads,
                                     {}, fixes[k]);
                }
                P->ok = true;
            } catch (...) {
                // Any failure: beginFrame reads this frame as without prefetch and reports it
                // there.
            }
        });
}

std::string ExrLoader::filePath(const std::string& role, int64_t frame) const {
    if (plan_.layout != Layout::Games202 || role.empty()) return pattern_->expand(frame);
    return FramePattern(games202Dir_ + role + games202Tail_).expand(frame);
}

std::vector<std::pair<std::string, std::string>> ExrLoader::filesRead(int64_t frame) const {
    if (!pattern_) return {};
    if (plan_.layout != Layout::Games202) {
        std::vector<std::pair<std::string, std::string>> files{{pattern_->expand(frame), "path"}};
        if (cameras_) files.push_back({cameras_->path().string(), "camera"});
        return files;
    }
    // Every sibling the layout names, read or not: an output over normal_1.exr destroys the
    // user's render whether this graph reads normals or not.
    std::vector<std::pair<std::string, std::string>> files;
    for (const char* role : kGames202Roles) files.push_back({filePath(role, frame), "path"});
    std::string mat = filePath("matrix", frame);
    if (mat.size() > 4 && mat.compare(mat.size() - 4, 4, ".exr") == 0)
        files.push_back({mat.substr(0, mat.size() - 4) + ".mat", "path"});
    return files;
}

std::vector<int64_t> ExrLoader::availableFrames() const {
    if (pattern_) return pattern_->findFrames();
    if (path_.empty()) return {};
    std::string p = path_;
    std::error_code ec;
    if (fs::is_directory(p, ec)) p = (fs::path(p) / "beauty_%d.exr").string();
    try {
        return FramePattern(p).findFrames();
    } catch (const Error&) {
        return {};
    }
}

namespace {

/// Whether folder `dir` (ending in '/') holds a GAMES202 beauty_N.exr file.
bool holdsGames202Beauty(const std::string& dir) {
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (name.rfind("beauty_", 0) == 0 && it->path().extension() == ".exr") return true;
    }
    return false;
}

/// A frame pattern for the EXR files in folder `dir` (ending in '/'): the first one's name with
/// its last run of digits as #### ("dir/frame_0001.exr" -> "dir/frame_####.exr"), else
/// dir/frame_####.exr.
std::string suggestedPattern(const std::string& dir) {
    std::error_code ec;
    std::vector<std::string> names;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
        if (it->path().extension() == ".exr") names.push_back(it->path().filename().string());
    if (names.empty()) return dir + "frame_####.exr (it holds no .exr file)";
    std::string name = *std::min_element(names.begin(), names.end());
    const size_t end = name.find_last_of("0123456789");
    if (end == std::string::npos) return dir + name;
    size_t begin = end;
    while (begin > 0 && std::isdigit(static_cast<unsigned char>(name[begin - 1]))) --begin;
    return dir + name.substr(0, begin) + std::string(end + 1 - begin, '#') + name.substr(end + 1);
}

/// The view layer to read: `wanted`, else the only one. Several and none chosen is refused (a
/// silent pick would denoise the wrong layer). nullopt: no Blender layer at all.
std::optional<std::string> chooseLayer(const std::vector<std::string>& layers,
                                       const std::string& wanted, const std::string& file) {
    std::string names;
    for (const auto& l : layers) names += (names.empty() ? "" : ", ") + l;
    if (!wanted.empty()) {
        if (std::find(layers.begin(), layers.end(), wanted) == layers.end())
            throw Error("layer '" + wanted + "': " + file +
                        (layers.empty() ? " has no Blender view layer ('<layer>.Combined.R')"
                                        : " has view layers " + names));
        return wanted;
    }
    if (layers.size() > 1)
        throw Error(file + " has " + std::to_string(layers.size()) + " view layers (" + names +
                    "): choose one with the loader's layer parameter (--set input.layer=" +
                    layers.front() + ")");
    if (layers.empty()) return std::nullopt;
    return layers.front();
}

}  // namespace

void ExrLoader::ensurePlan(int64_t frame, std::vector<std::string>* notes) {
    if (planned_) return;
    if (path_.empty()) throw Error("ExrLoader: parameter 'path' is empty: give a frame pattern");
    auto note = [&](std::string s) {
        if (notes) notes->push_back(std::move(s));
    };

    // Which files: a GAMES202 folder or beauty_ pattern, else one multi-channel file per frame.
    std::string pattern = path_;
    std::error_code ec;
    bool games202 = layoutParam_ == "games202";
    const bool folder = fs::is_directory(pattern, ec);
    if (folder) {
        std::string dir = pattern.back() == '/' ? pattern : pattern + "/";
        // Only GAMES202's layout is a folder of files per frame; any other folder is the
        // user's slip for a pattern, said with the pattern its files suggest.
        if ((layoutParam_ != "auto" && layoutParam_ != "games202") ||
            (layoutParam_ == "auto" && !holdsGames202Beauty(dir)))
            throw Error("path " + path_ + " is a folder" +
                        (layoutParam_ == "auto" ? " without GAMES202's beauty_N.exr files" : "") +
                        ": give a frame pattern such as " + suggestedPattern(dir));
        pattern = dir + "beauty_%d.exr";
        games202 = true;
    }
    pattern_ = std::make_unique<FramePattern>(pattern);
    std::string file = pattern.substr(parentDir(pattern).size());
    const bool namedLikeBeauty = layoutParam_ == "auto" && !folder && file.rfind("beauty", 0) == 0;
    if (namedLikeBeauty) games202 = true;
    if (games202) {
        if (file.rfind("beauty", 0) != 0)
            throw Error("layout games202: path " + path_ +
                        " must be a folder or name the beauty files (dir/beauty_%d.exr)");
        games202Dir_ = parentDir(pattern);
        games202Tail_ = file.substr(6);
    }

    // First frame: the requested one, else the first found on disk.
    int64_t first = frame;
    std::string firstPath = pattern_->expand(first);
    if (!fs::exists(firstPath, ec)) {
        auto found = pattern_->findFrames();
        if (found.empty())
            throw Error("no input frame: " + firstPath + " does not exist and nothing matches " +
                        pattern);
        note("frame " + std::to_string(first) + " missing; layout probed on frame " +
             std::to_string(found.front()));
        first = found.front();
        firstPath = pattern_->expand(first);
    }

    // A file merely named beauty.####.exr is a multi-channel frame unless GAMES202's other
    // buffers lie beside it (its normal_ or depth_ file for the same frame).
    if (namedLikeBeauty &&
        !fs::exists(FramePattern(games202Dir_ + "normal" + games202Tail_).expand(first), ec) &&
        !fs::exists(FramePattern(games202Dir_ + "depth" + games202Tail_).expand(first), ec)) {
        games202 = false;
        note("named like GAMES202's beauty files, but no normal or depth file lies beside " +
             firstPath + ": one multi-channel file per frame");
    }

    ChannelSets sets;
    std::unique_ptr<ExrInput> probed;  // the first file (single-file layouts)
    if (games202) {
        plan_.layout = Layout::Games202;
        for (const char* role : kGames202Roles) {
            std::string p = filePath(role, first);
            if (!fs::exists(p, ec)) continue;
            try {
                ExrInput in(p, maxPixels_);
                sets[role] = channelNames(in.header());
                if (std::string(role) == "beauty") rememberFirstFrame(first, in);
            } catch (const Error& e) {
                throw Error(p + ": " + e.what());
            }
        }
        if (!sets.count("beauty")) throw Error(firstPath + ": file not found");
        plan_ = planGames202(sets);
        std::string mat = filePath("matrix", first);
        mat = mat.substr(0, mat.size() - 4) + ".mat";
        games202Matrices_ = games202Tail_.size() > 4 &&
                            games202Tail_.compare(games202Tail_.size() - 4, 4, ".exr") == 0 &&
                            fs::exists(mat, ec);
        note(games202Matrices_ ? "camera and object matrices from " + mat
                               : "no matrix file " + mat + ": no camera matrices");
    } else {
        std::unique_ptr<ExrInput>& in = probed;
        try {
            in = std::make_unique<ExrInput>(firstPath, maxPixels_);
        } catch (const Error& e) {
            throw Error(firstPath + ": " + e.what());
        }
        sets[""] = channelNames(in->header());
        rememberFirstFrame(first, *in);
        const auto layers = blenderLayers(sets[""]);
        const auto* tag = in->header().findTypedAttribute<Imf::StringAttribute>("kestrel.layout");
        Layout layout = Layout::Canonical;
        if (layoutParam_ == "blender" || (layoutParam_ == "auto" && !tag && !layers.empty()))
            layout = Layout::Blender;
        if (layout == Layout::Blender) {
            const auto layer = chooseLayer(layers, layerParam_, firstPath);
            if (!layer)
                throw Error("layout blender: " + firstPath +
                            " has no '<layer>.Combined.R' channel (not a Cycles multilayer EXR)");
            note("Blender view layer '" + *layer + "'");
            // camera.json: the parameter, else beside the frames, else one folder up.
            fs::path cam = cameraParam_;
            if (cam.empty()) {
                fs::path dir = fs::path(firstPath).parent_path();
                if (dir.empty()) dir = ".";
                for (fs::path c : {dir / "camera.json", dir.parent_path() / "camera.json"})
                    if (fs::exists(c, ec)) {
                        cam = c;
                        break;
                    }
            } else if (!fs::exists(cam, ec)) {
                throw Error("camera file " + cam.string() + " not found");
            }
            if (!cam.empty()) cameras_ = std::make_unique<BlenderCameras>(cam);
            plan_ = planBlender(sets, *layer);
            if (cameras_) {
                note("cameras from " + cam.string());
            } else {
                note("no camera.json beside the frames or one folder up: no camera matrices");
                if (plan_.find("normal")->cameraSpace)
                    note(
                        "normal: Denoising Normal stays in camera space (no camera to rotate it "
                        "by)");
            }
        } else {
            if (!layerParam_.empty())  // a layer choice that would silently do nothing
                throw Error("layer '" + layerParam_ + "': " + firstPath +
                            " is not a Blender multilayer EXR (layout canonical): it has no view "
                            "layers");
            plan_ = planCanonical(sets);
            if (!tag)
                note("no kestrel.layout attribute: reading canonical channel names");
            else if (tag->value() != "canonical")
                throw Error(firstPath + ": kestrel.layout is '" + tag->value() +
                            "', this loader reads 'canonical'");
        }
    }
    std::set<std::string> overridden;
    if (!channelsParam_.empty()) overridden = applyChannelOverrides(plan_, channelsParam_, sets);
    for (const char* o : {"color", "diffuse", "specular", "emission"})
        if (overridden.count(o)) {
            addSplitRest(plan_, overridden);
            break;
        }
    planAntiAliasing(probed.get(), overridden);
    note(antiAliasing_.why);  // the decision, once per run, with why (PixelJitter.h)
    colorHalf_ = storedAsHalf("color", probed.get(), first);
    depthHalf_ = storedAsHalf("depth", probed.get(), first);
    if (!overridden.count("position")) planPositionFromDepth(probed.get());
    if (!overridden.count("normal")) planNormalFromDepth(probed.get());
    if (Recipe& reflection = *plan_.find("reflection");
        reflection.reflectionOf && !hasCamera(probed.get())) {
        reflection.reflectionOf.reset();
        reflection.absent = true;
        reflection.why = "no camera (camera.json) to turn Denoising Normal to world space";
    }
    if (!overridden.count("motion")) planSkyMotion();
    note(std::string("layout ") + layoutName(plan_.layout) + " (" + firstPath + ")");
    for (const auto& r : plan_.recipes)
        if (!r.absent) note(r.output + " = " + r.why);
    planned_ = true;
}

bool ExrLoader::storedAsHalf(const std::string& output, const ExrInput* first,
                             int64_t frame) const {
    const Recipe* recipe = plan_.find(output);
    if (!recipe || recipe->absent) return false;
    const auto refs = recipe->channels();
    if (refs.empty()) return false;
    std::map<std::string, std::unique_ptr<ExrInput>> opened;  // GAMES202: each role file once
    for (const auto& ref : refs) {
        const ExrInput* in = first;
        if (!ref.file.empty() || !in) {
            auto& other = opened[ref.file];
            try {
                if (!other)
                    other = std::make_unique<ExrInput>(filePath(ref.file, frame), maxPixels_);
            } catch (const Error&) {
                return false;  // reported where the frame is read
            }
            in = other.get();
        }
        const Imf::Channel* c = in->header().channels().findChannel(ref.name);
        if (!c || c->type != Imf::HALF) return false;
    }
    return true;
}

std::optional<float> ExrLoader::statedFilterWidth(const ExrInput* first) const {
    if (plan_.layout == Layout::Blender)
        return cameras_ ? cameras_->pixelFilterWidth() : std::nullopt;
    if (!first) return std::nullopt;
    const auto* a =
        first->header().findTypedAttribute<Imf::FloatAttribute>("kestrel.pixelFilterWidth");
    if (!a || !std::isfinite(a->value())) return std::nullopt;
    return std::max(0.f, a->value());
}

std::optional<float> ExrLoader::measureDepthJitter(ExrInput* first) const {
    const Recipe& depth = *plan_.find("depth");
    if (!first || depth.absent || !depth.isDirect() || !depth.terms[0][0][0].file.empty())
        return std::nullopt;
    const Box dp = first->displayWindow();
    const int W = int(dp.width()), H = int(dp.height());
    std::vector<float> z(size_t(W) * size_t(H));
    try {
        readChannels(*first, dp, W, z.size(), {{depth.terms[0][0][0].name, z.data()}}, {depth.fill},
                     1);
    } catch (const std::exception&) {
        // Damaged pixels cannot be measured; the frame reports its damage when it is read
        // (a FrameError, which --skip-bad-frames skips), not the compile.
        return std::nullopt;
    }
    return depthJitterScore(z.data(), W, H);
}

void ExrLoader::unprojectDepth(FrameContext& ctx, const float* depth, bool rayLength,
                               const ImageView& out, int W, int H) const {
    const size_t N = size_t(W) * size_t(H);
    std::optional<Mat4> cameraToWorld;
    if (ctx.scene && ctx.scene->hasCamera) cameraToWorld = inverse(ctx.scene->worldToCamera);
    if (!cameraToWorld) {  // this frame has no camera: no positions (Reprojection: disocclusion)
        for (int c = 0; c < 3; ++c) fillPlane(asFloats(out, c), N, 0.f);
        return;
    }
    const Mat4 cameraToPixel = ctx.scene->worldToPixel * *cameraToWorld;
    ctx.parallelRows(H, [&](int y0, int y1) {
        unprojectRows(cameraToPixel, *cameraToWorld, depth, rayLength,
                      {asFloats(out, 0), asFloats(out, 1), asFloats(out, 2)}, W, y0, y1);
    });
}

void ExrLoader::skyMotion(FrameContext& ctx, const float* depth, const ImageView& motion, int W,
                          int H) const {
    if (!cameras_) {  // the sky's motion is unknown: no history is reused there
        const float unknown = std::numeric_limits<float>::quiet_NaN();
        float *mx = asFloats(motion, 0), *my = asFloats(motion, 1);
        ctx.parallelRows(H, [&](int y0, int y1) {
            for (size_t i = size_t(y0) * size_t(W); i < size_t(y1) * size_t(W); ++i)
                if (!(depth[i] > 0.f) || depth[i] >= 1e9f) mx[i] = my[i] = unknown;
        });
        return;
    }
    SceneData prev;
    if (!ctx.scene || !ctx.scene->hasCamera || !cameras_->fill(frame_ - 1, prev) || !prev.hasCamera)
        return;  // no previous camera (the shot's first frame): Blender's 0 stays
    const std::optional<Mat4> cameraToWorld = inverse(ctx.scene->worldToCamera);
    if (!cameraToWorld) return;
    const Mat4 cameraToPixel = ctx.scene->worldToPixel * *cameraToWorld;
    ctx.parallelRows(H, [&](int y0, int y1) {
        skyMotionRows(cameraToPixel, *cameraToWorld, prev.worldToPixel, depth,
                      {asFloats(motion, 0), asFloats(motion, 1)}, W, y0, y1);
    });
}

void ExrLoader::planSkyMotion() {
    Recipe& motion = *plan_.find("motion");
    const Recipe& depth = *plan_.find("depth");
    // Blender's Vector pass is 0 on the background even when the camera turns
    // (data/README.md): a sky's history would stay where it was on screen.
    if (plan_.layout != Layout::Blender || motion.absent || depth.absent || !depth.isDirect())
        return;
    motion.skyDepth = depth.terms[0][0][0];
    // Without camera.json the turn is unknown: the background's motion is NaN, which
    // Reprojection rejects (a sky held still while the camera pans smeared it: the
    // background of blender-street-defaults without camera.json 47.5 dB at 1 spp, 44.4 after).
    motion.why += cameras_ ? "; on the background from the cameras' rotation"
                           : "; unknown (NaN) on the background: no camera.json to turn it";
}

bool ExrLoader::hasCamera(const ExrInput* first) const {
    if (cameras_) return true;  // camera.json (Blender)
    if (plan_.layout != Layout::Canonical || !first) return false;
    const Imf::Header& h = first->header();
    return h.findTypedAttribute<Imf::M44fAttribute>("kestrel.worldToPixel") &&
           h.findTypedAttribute<Imf::M44fAttribute>("kestrel.worldToCamera");
}

void ExrLoader::planPositionFromDepth(const ExrInput* first) {
    Recipe& position = *plan_.find("position");
    const Recipe& depth = *plan_.find("depth");
    // A render without the Position pass (Blender's usual set-up: Z or Denoising Data only)
    // would otherwise leave a graph without motion vectors no way to reproject but the
    // identity. The camera: camera.json (Blender) or the canonical file's matrices.
    if (!position.absent || depth.absent || !depth.isDirect() || !hasCamera(first)) return;
    position.terms = {{{depth.terms[0][0][0]}}};
    position.fromDepth = true;
    position.rayLength = depth.zeroIsBackground;  // Denoising Depth: distance along the ray
    position.absent = false;
    position.why = "unprojected from " + depth.terms[0][0][0].str() + " with " +
                   (cameras_ ? cameras_->path().filename().string() : "the file's camera") +
                   " (no position channels)";
}

void ExrLoader::planNormalFromDepth(const ExrInput* first) {
    Recipe& normal = *plan_.find("normal");
    const Recipe& depth = *plan_.find("depth");
    // A render with neither Normal nor Denoising Normal (Blender: Combined and Z only) would
    // leave every edge-stopping filter without its normal term; geometric normals from the
    // depth keep the filters from blurring across creases.
    if (!normal.absent || depth.absent || !depth.isDirect() || !hasCamera(first)) return;
    const std::string missing = normal.why;
    normal.terms = {{{depth.terms[0][0][0]}}};
    normal.fromDepth = true;
    normal.rayLength = depth.zeroIsBackground;  // Denoising Depth: distance along the ray
    normal.cameraSpace = normal.zeroIsBackground = false;
    normal.absent = false;
    normal.why = "reconstructed from " + depth.terms[0][0][0].str() + " with " +
                 (cameras_ ? cameras_->path().filename().string() : "the file's camera") +
                 " (geometric normals, no bump or smoothing; " + missing + ")";
}

void ExrLoader::normalsFromDepth(FrameContext& ctx, const float* depth, bool rayLength,
                                 const ImageView& out, int W, int H) const {
    const size_t N = size_t(W) * size_t(H);
    std::optional<Mat4> cameraToWorld;
    if (ctx.scene && ctx.scene->hasCamera) cameraToWorld = inverse(ctx.scene->worldToCamera);
    if (!cameraToWorld) {  // this frame has no camera: no normals (as the background)
        for (int c = 0; c < 3; ++c) fillPlane(asFloats(out, c), N, 0.f);
        return;
    }
    // Positions of the whole frame first (a transient 12 B/px, only on renders without a
    // normal pass): each pixel's normal reads its neighbours'.
    std::vector<float> pos(3 * N);
    const std::array<float*, 3> p = {pos.data(), pos.data() + N, pos.data() + 2 * N};
    const Mat4 cameraToPixel = ctx.scene->worldToPixel * *cameraToWorld;
    ctx.parallelRows(H, [&](int y0, int y1) {
        unprojectRows(cameraToPixel, *cameraToWorld, depth, rayLength, p, W, y0, y1);
    });
    const auto& M = cameraToWorld->m;
    const double eye[3] = {M[0][3], M[1][3], M[2][3]};
    ctx.parallelRows(H, [&](int y0, int y1) {
        normalsFromPositionsRows({p[0], p[1], p[2]}, depth, eye,
                                 {asFloats(out, 0), asFloats(out, 1), asFloats(out, 2)}, W, H, y0,
                                 y1);
    });
}

void ExrLoader::planAntiAliasing(ExrInput* first, const std::set<std::string>& overridden) {
    if (antiAliasedParam_ != "auto") {
        antiAliasing_ = {antiAliasedParam_ == "true", "antiAliased parameter " + antiAliasedParam_};
    } else {
        const auto stated = statedFilterWidth(first);
        if (!stated && plan_.layout == Layout::Blender)
            antiAliasing_ = decideBlenderAntiAliasing(measureDepthJitter(first));
        else
            antiAliasing_ =
                decideAntiAliasing(stated, stated ? std::nullopt : measureDepthJitter(first));
    }
    const AntiAliasing& aa = antiAliasing_;
    // On an anti-aliased render a pixel's features are one sample of its footprint: a window's
    // glass reflects the sky in one frame and is the wall's edge in the next, and the chains'
    // albedo, averaged over frames, mixes both. Joined by the reversed normal, the glass pixels
    // then spread light demodulated by the glass's albedo onto pixels re-modulated by the wall's
    // (blender-street-defaults, svgf.json frames 5-12: 33.35 -> 32.88 dB); the zero normal keeps
    // each pixel to itself there, as before.
    if (aa.antiAliased && !overridden.count("normal")) plan_.find("normal")->zeroFallback.reset();
    for (const auto& o : loaderOutputs()) {
        const char* base = jitteredOf(o.name);
        if (!base || overridden.count(o.name)) continue;
        Recipe& out = *plan_.find(o.name);
        const Recipe& albedo = *plan_.find(base);
        auto absent = [&](std::string why) {
            out.terms.clear();
            out.absent = true;
            out.why = std::move(why);
        };
        if (albedo.absent) {
            absent("no " + std::string(base) + " (" + albedo.why + ")");
            continue;
        }
        if (!aa.antiAliased) {
            absent(aa.why);
            continue;
        }
        out.terms = albedo.terms;
        out.absent = false;
        out.why = albedo.why + ": " + aa.why;
    }
}

void ExrLoader::resolve(ResolveContext& rc) {
    std::vector<std::string> notes;
    ensurePlan(rc.firstFrame(), &notes);
    for (auto& n : notes) rc.note(std::move(n));
    rc.setFact("antiAliased", antiAliasing_.antiAliased ? "true" : "false");
    // The precision the colour arrives in: a writer with pixelType auto keeps it (a noise-free
    // float sky written as half loses up to 2^-11 of its value, more than 1 spp's error there).
    rc.setFact("colorPixelType", colorHalf_ ? "half" : "float");
    // Depth stored as half (Blender's "Float (Half)" EXR option) steps by up to 2^-10 of its
    // value: edge-stopping filters widen their depth tolerance by that much
    // (kestrel::kDepthPrecisionFact).
    if (depthHalf_) rc.setFact(kDepthPrecisionFact, "0.0009765625");
    stateSourceFacts(rc, plan_, pattern_.get());  // for a writer's keepPasses
    for (const auto& r : plan_.recipes)
        if (r.absent) rc.setAbsent(r.output, r.why);
}

ExrInput& ExrLoader::openRole(const std::string& role, int64_t frame) {
    for (auto& [r, in] : open_)
        if (r == role) return *in;
    std::string p = filePath(role, frame);
    try {
        auto in = std::make_unique<ExrInput>(p, maxPixels_);
        if (!open_.empty() && in->displayWindow() != display_)
            throw Error("display window differs from the frame's " + open_.front().second->path());
        open_.emplace_back(role, std::move(in));
    } catch (const Error& e) {
        throw FrameError("frame " + std::to_string(frame) + ": " + p + ": " + e.what());
    }
    return *open_.back().second;
}

void ExrLoader::rememberFirstFrame(int64_t frame, const ExrInput& in) {
    firstFrame_ = {frame, in.path(), in.displayWindow().width(), in.displayWindow().height()};
}

void ExrLoader::checkFrameSize(const ExrInput& in) const {
    const int64_t W = in.displayWindow().width(), H = in.displayWindow().height();
    if (firstFrame_.path.empty() || (W == firstFrame_.width && H == firstFrame_.height)) return;
    // A re-render at another size mid-shot (or a stray file): filtering it with the history of
    // the others is meaningless, and resetting history silently hid it.
    throw FrameError(fmt::format(
        "frame {}: {}: the frame is {}x{}, the first frame ({}, frame {}) is {}x{}: every frame "
        "of a sequence must have the first frame's size (--skip-bad-frames skips it)",
        frame_, in.path(), W, H, firstFrame_.path, firstFrame_.frame, firstFrame_.width,
        firstFrame_.height));
}

void ExrLoader::fillScene(int64_t frame, SceneData& scene) {
    scene = SceneData{};
    if (plan_.layout == Layout::Blender && cameras_) {
        if (!cameras_->fill(frame, scene))  // a frame written after beginRun's check
            throw FrameError("frame " + std::to_string(frame) + ": " + cameraGap({frame}));
    } else if (plan_.layout == Layout::Games202 && games202Matrices_) {
        std::string mat = filePath("matrix", frame);
        mat = mat.substr(0, mat.size() - 4) + ".mat";
        try {
            readGames202Matrices(mat, scene);
        } catch (const Error& e) {
            throw FrameError("frame " + std::to_string(frame) + ": " + mat + ": " + e.what());
        }
    } else if (plan_.layout == Layout::Canonical) {
        const Imf::Header& h = open_.front().second->header();
        if (auto* a = h.findTypedAttribute<Imf::M44fAttribute>("kestrel.worldToPixel")) {
            scene.hasCamera = true;
            scene.worldToPixel = toMat4(a->value());
        }
        if (auto* a = h.findTypedAttribute<Imf::M44fAttribute>("kestrel.worldToCamera"))
            scene.worldToCamera = toMat4(a->value());
        const std::string prefix = "kestrel.objectToWorld.";
        for (auto it = h.begin(); it != h.end(); ++it) {
            std::string name = it.name();
            if (name.rfind(prefix, 0) != 0) continue;
            auto* a = dynamic_cast<const Imf::M44fAttribute*>(&it.attribute());
            if (!a) continue;
            try {
                scene.objectToWorld[std::stoi(name.substr(prefix.size()))] = toMat4(a->value());
            } catch (const std::exception&) {
                // a non-numeric suffix is someone else's attribute
            }
        }
    }
}

std::optional<Extent> ExrLoader::beginFrame(FrameContext& ctx) {
    ensurePlan(ctx.frameNumber, nullptr);
    joinPrefetch();  // before the pool is resized: the read-ahead decodes on it
    // OpenEXR decodes line blocks on its own global pool (the engine's thread count).
    const int threads = ctx.parallel ? ctx.parallel->threadCount() : 1;
    if (Imf::globalThreadCount() < threads) Imf::setGlobalThreadCount(threads);
    threads_ = threads;

    if (haveLast_ && ctx.frameNumber > frame_) step_ = ctx.frameNumber - frame_;
    haveLast_ = true;
    frame_ = ctx.frameNumber;
    open_.clear();
    // A frame read ahead: adopt its open files and planes; anything else is dropped.
    ready_.reset();
    if (pending_) {
        if (pending_->ok && pending_->frame == frame_) {
            ready_ = std::move(pending_);
            open_ = std::move(ready_->open);
        } else {
            spare_ = std::move(pending_->planes);
            pending_.reset();
        }
    }
    std::string primary = plan_.layout == Layout::Games202 ? "beauty" : "";
    ExrInput& in = openRole(primary, frame_);
    display_ = in.displayWindow();
    checkFrameSize(in);
    // Channels the first frame had must still be there (a half-written or foreign file).
    const Imf::ChannelList& list = in.header().channels();
    for (const auto& r : plan_.recipes) {
        if (r.absent) continue;
        for (const auto& c : r.channels())
            if (c.file == primary && !list.findChannel(c.name))
                throw FrameError("frame " + std::to_string(frame_) + ": " + in.path() +
                                 ": no channel " + c.name + " (the first frame had it)");
    }
    if (ctx.scene) fillScene(frame_, *ctx.scene);
    return Extent{int(display_.width()), int(display_.height())};
}

/// Recipe::reflectionOf: 1 where Cycles' Denoising Normal (camera space, read before the
/// convention fixes turn it) is zero on a surface or more than ~8 degrees from the Normal pass
/// (world space, turned to camera space here), else 0. Without a camera this frame: 0.
static void reflectionMask(FrameContext& ctx, const std::pair<Factor, Factor>& of,
                           const std::map<ChannelRef, float*>& dest, const ImageView& out,
                           size_t n) {
    float* o = asFloats(out, 0);
    if (!ctx.scene || !ctx.scene->hasCamera) {
        std::fill(o, o + n, 0.f);
        return;
    }
    const auto& m = ctx.scene->worldToCamera.m;
    const float* d[3] = {dest.at(of.first[0]), dest.at(of.first[1]), dest.at(of.first[2])};
    const float* g[3] = {dest.at(of.second[0]), dest.at(of.second[1]), dest.at(of.second[2])};
    for (size_t i = 0; i < n; ++i) {
        const float gx = px::sanitizeNormal(g[0][i]), gy = px::sanitizeNormal(g[1][i]),
                    gz = px::sanitizeNormal(g[2][i]);
        // World to Cycles' camera space (x right, y up, z forward: rotateToWorld's inverse).
        const float cx = m[0][0] * gx + m[0][1] * gy + m[0][2] * gz;
        const float cy = m[1][0] * gx + m[1][1] * gy + m[1][2] * gz;
        const float cz = -(m[2][0] * gx + m[2][1] * gy + m[2][2] * gz);
        const float dx = px::sanitizeNormal(d[0][i]), dy = px::sanitizeNormal(d[1][i]),
                    dz = px::sanitizeNormal(d[2][i]);
        const bool surface = gx != 0.f || gy != 0.f || gz != 0.f;
        const bool none = dx == 0.f && dy == 0.f && dz == 0.f;
        o[i] = surface && (none || dx * cx + dy * cy + dz * cz < 0.99f) ? 1.f : 0.f;
    }
}

/// Where all three channels of `out` are zero, the fallback's channels reversed
/// (Recipe::zeroFallback): the sky or light a mirror shows is filtered with itself, across the
/// mirror, and never with the mirror's frame or the wall around it, whose normal is the
/// fallback's own (dot -1: every normal test rejects it).
static void fillZeroVectors(const Factor& fallback, const std::map<ChannelRef, float*>& dest,
                            const ImageView& out, size_t n) {
    float* o[3] = {asFloats(out, 0), asFloats(out, 1), asFloats(out, 2)};
    const float* f[3] = {dest.at(fallback[0]), dest.at(fallback[1]), dest.at(fallback[2])};
    for (size_t i = 0; i < n; ++i)
        if (o[0][i] == 0.f && o[1][i] == 0.f && o[2][i] == 0.f)
            for (int c = 0; c < 3; ++c) o[c][i] = -f[c][i];
}

/// Warns once for the frame, counting by output channel, where the policy replaced values.
void ExrLoader::warnReplaced(const std::vector<std::pair<std::string, size_t>>& replaced) const {
    std::string counts;
    for (const auto& [channel, n] : replaced)
        if (n) counts += fmt::format("{}{} in {}", counts.empty() ? "" : ", ", n, channel);
    // One line per frame: a whole damaged sequence says so on every frame it damages.
    if (!counts.empty())
        spdlog::warn(
            "frame {}: {}: NaN, infinite or absurd (|v| > 1e30, light < -1e8, albedo < 0) input "
            "values "
            "replaced by the output's fill value, as for a missing channel (docs/layouts.md): {}",
            frame_, open_.empty() ? path_ : open_.front().second->path(), counts);
}

/// A computed output (positions, normals from depth): its absurd values replaced by `fill`
/// in a pass of its own (renders without those passes only); how many per channel.
static std::array<size_t, 4> replaceAbsurdInPlanes(FrameContext& ctx, const ImageView& out, int W,
                                                   int H, float fill) {
    std::array<std::atomic<size_t>, 4> count{};
    ctx.parallelRows(H, [&](int y0, int y1) {
        for (int c = 0; c < std::min(4, out.channels()); ++c)
            if (const size_t n = replaceAbsurd(asFloats(out, c) + size_t(y0) * size_t(W),
                                               size_t(y1 - y0) * size_t(W), fill))
                count[size_t(c)] += n;
    });
    return {count[0].load(), count[1].load(), count[2].load(), count[3].load()};
}

namespace {

/// A direct output channel that a sum, the rest or a derived output reads raw: its absurd
/// values are replaced after them, in [b, e) of its plane, counted (the channel's own plane;
/// a copy of it in a second output is not counted again).
struct Deferred {
    float* plane;
    float fill, lowest;
    std::atomic<size_t>* replaced;  // null: a copy
    bool afterDerived;              // a derived output reads it: after those, in a pass
    void replace(size_t b, size_t e) const {
        const size_t n = replaceAbsurd(plane + b, e - b, fill, lowest);
        if (n && replaced) *replaced += n;
    }
};

/// The channels that sums, the rest (Recipe::Rest; fastRest: from the colour, diffuse and
/// emission planes) and derived outputs read.
std::set<ChannelRef> channelsReadRaw(const std::vector<const Recipe*>& composite,
                                     const std::vector<const Recipe*>& derived,
                                     const Recipe* fastRest, const Plan& plan) {
    std::set<ChannelRef> raw;
    for (const auto* list : {&composite, &derived})
        for (const Recipe* r : *list)
            for (const auto& c : r->channels()) raw.insert(c);
    if (fastRest)
        for (const char* o : {"color", "diffuse", "emission"})
            if (const Recipe* x = plan.find(o); x && !x->absent && x->isDirect())
                for (const auto& c : x->terms[0][0]) raw.insert(c);
    return raw;
}

}  // namespace

/// The values the policy replaced this frame per output channel ("color.R"), in plan order:
/// decoded channels counted by the decoder (a channel copied to a second output counts there
/// too), sums by their blocks; outputs computed from depth are checked here.
static std::vector<std::pair<std::string, size_t>> replacedByOutput(
    FrameContext& ctx, PassIO& io, const std::vector<const Recipe*>& active,
    const std::vector<const Recipe*>& composite,
    const std::vector<std::array<std::atomic<size_t>, 4>>& compositeReplaced,
    const std::map<ChannelRef, std::atomic<size_t>>& decoded, int W, int H) {
    std::vector<std::pair<std::string, size_t>> counts;
    for (const Recipe* r : active) {
        if (r->reflectionOf) continue;  // 0 or 1 only
        const ImageView& out = io.output(r->output);
        std::array<size_t, 4> n{};
        if (r->fromDepth) {
            n = replaceAbsurdInPlanes(ctx, out, W, H, r->fill);
        } else if (r->isDirect()) {
            for (size_t c = 0; c < r->terms[0][0].size() && c < 4; ++c)
                n[c] = decoded.at(r->terms[0][0][c]).load();
        } else {
            const size_t k =
                size_t(std::find(composite.begin(), composite.end(), r) - composite.begin());
            for (size_t c = 0; c < 4; ++c) n[c] = compositeReplaced[k][c].load();
        }
        for (int c = 0; c < std::min(4, std::max(1, out.channels())); ++c)
            counts.emplace_back(r->output + "." + "RGBA"[c], n[size_t(c)]);
    }
    return counts;
}

void ExrLoader::execute(FrameContext& ctx, PassIO& io) {
    const int W = int(display_.width()), H = int(display_.height());
    const size_t N = size_t(W) * size_t(H);

    // Where each file channel goes: straight into an output plane when the output is that
    // channel alone, else into a scratch plane feeding sums and products.
    std::map<ChannelRef, float*> dest;
    std::map<ChannelRef, float> fills;
    std::vector<std::pair<float*, ChannelRef>> copies;  // a channel wanted in two output planes
    std::vector<const Recipe*> composite, active, derived;
    for (const auto& r : plan_.recipes) {
        if (!io.hasOutput(r.output)) continue;
        const ImageView& out = io.output(r.output);
        if (r.absent) {  // only in unit tests: the engine never binds an absent output
            for (int c = 0; c < std::max(1, out.channels()); ++c)
                fillPlane(asFloats(out, c), N, r.fill);
            if (r.format == Format::Int32) floatsToIds(asFloats(out, 0), N, IdRule::Round);
            continue;
        }
        active.push_back(&r);
        if (r.fromDepth || r.reflectionOf) {  // computed below from channels read to scratch
            derived.push_back(&r);
            continue;
        }
        if (r.isDirect()) {
            const Factor& f = r.terms[0][0];
            for (size_t c = 0; c < f.size(); ++c) {
                if (dest.count(f[c])) {
                    copies.emplace_back(asFloats(out, int(c)), f[c]);
                } else {
                    dest[f[c]] = asFloats(out, int(c));
                    fills[f[c]] = r.fill;
                }
            }
        } else {
            composite.push_back(&r);
        }
    }
    std::vector<ChannelRef> scratchRefs;
    for (const Recipe* r : active) {
        for (const auto& c : r->channels())
            if (!dest.count(c) &&
                std::find(scratchRefs.begin(), scratchRefs.end(), c) == scratchRefs.end())
                scratchRefs.push_back(c);
    }
    if (scratchPixels_ != N || scratch_.size() < scratchRefs.size()) {
        if (scratchPixels_ != N) scratch_.clear();
        while (scratch_.size() < scratchRefs.size()) scratch_.push_back(allocatePlane(N));
        scratchPixels_ = N;
    }
    for (size_t i = 0; i < scratchRefs.size(); ++i) {
        dest[scratchRefs[i]] = scratch_[i].get();
        const ChannelRef& mask = scratchRefs[i];
        bool isMask = false;
        for (const Recipe* r : active) isMask |= r->backgroundMask && *r->backgroundMask == mask;
        fills[mask] = isMask ? float(kBackgroundId) : 0.f;
    }

    // Specular's rest from the colour, diffuse and emission planes when this frame computes
    // them (they come first in the plan; svgf.json binds all three): three reads per pixel
    // instead of every split term again, and the emission tightened in place.
    const Recipe* fastRest = nullptr;
    const Recipe* spec = plan_.find("specular");
    const bool emissionBound = io.hasOutput("emission") && !plan_.find("emission")->absent;
    if (spec->rest && spec->rest->part == Recipe::Rest::Part::Positive &&
        io.hasOutput("specular") && io.hasOutput("color") && io.hasOutput("diffuse") &&
        !plan_.find("color")->absent && !plan_.find("diffuse")->absent)
        fastRest = spec;

    // Decode, file by file. A channel decoded straight into its output has its absurd values
    // replaced as it is decoded (Absurd.h), unless a sum, the rest or a derived output reads
    // it: those read it raw (a non-finite pass adds no light to the rest) and it is replaced
    // after them (Deferred). Scratch channels stay raw.
    std::map<ChannelRef, float> direct;  // -> the lowest valid value (its output's)
    for (const Recipe* r : active)
        if (r->isDirect() && !r->fromDepth && !r->reflectionOf)
            for (const auto& c : r->terms[0][0]) direct.emplace(c, r->lowest);
    std::map<ChannelRef, std::atomic<size_t>> replaced;
    for (const auto& [ref, lowest] : direct)
        replaced[ref];  // no insertion while decoding threads add
    const std::set<ChannelRef> readRaw = channelsReadRaw(composite, derived, fastRest, plan_);
    std::set<ChannelRef> readByDerived;
    for (const Recipe* r : derived)
        for (const auto& c : r->channels()) readByDerived.insert(c);
    std::map<ChannelRef, float> decodeFix;  // direct channels replaced as decoded
    std::vector<Deferred> deferred;
    for (const auto& [ref, lowest] : direct) {
        if (!readRaw.count(ref)) {
            decodeFix.emplace(ref, lowest);
            continue;
        }
        const bool late = readByDerived.count(ref) > 0;
        deferred.push_back({dest[ref], fills[ref], lowest, &replaced[ref], late});
        for (const auto& [plane, r] : copies)
            if (r == ref) deferred.push_back({plane, fills[ref], lowest, nullptr, late});
    }
    channelsRead_.clear();
    std::map<std::string, std::vector<std::pair<std::string, float*>>> byFile;
    for (const auto& [ref, plane] : dest) {
        byFile[ref.file].emplace_back(ref.name, plane);
        channelsRead_.push_back(ref.str());
    }
    bool adopted = ready_ != nullptr;
    for (const auto& [ref, plane] : dest) adopted = adopted && ready_->planes.count(ref);
    size_t fileBytes = 0;
    for (const auto& [role, chans] : byFile) {
        ExrInput& in = openRole(role, frame_);
        std::error_code ec;
        fileBytes += size_t(fs::file_size(in.path(), ec));
        if (adopted) {
            for (const auto& [name, plane] : chans) {
                if (decodeFix.count({role, name}))
                    replaced[{role, name}] = ready_->replaced[{role, name}].load();
                const float* src = ready_->planes[{role, name}].get();
                float* dst = plane;
                ctx.parallelRows(H, [&](int y0, int y1) {
                    std::copy(src + size_t(y0) * size_t(W), src + size_t(y1) * size_t(W),
                              dst + size_t(y0) * size_t(W));
                });
            }
            continue;
        }
        std::vector<float> fillv;
        std::vector<AbsurdFix> fixes;
        for (const auto& [name, plane] : chans) {
            const ChannelRef ref{role, name};
            fillv.push_back(fills[ref]);
            const auto d = decodeFix.find(ref);
            fixes.push_back({d != decodeFix.end(), fills[ref],
                             d != decodeFix.end() ? &replaced[ref] : nullptr,
                             d != decodeFix.end() ? d->second : -kAbsurd});
        }
        try {
            // The chunk buffers in planes the graph's memory plan leaves idle while the loader
            // runs, rather than in memory of their own on top of the plan's (docs/benchmarks.md).
            const Workspace lent{io.idlePlanes(), ctx.extent.pixels() * sizeof(float)};
            readChannels(in, display_, W, N, chans, fillv,
                         ctx.parallel ? ctx.parallel->threadCount() : 1, lent, fixes);
        } catch (const std::exception& e) {
            throw FrameError("frame " + std::to_string(frame_) + ": " + in.path() +
                             ": cannot read pixels (corrupt or truncated): " + e.what());
        }
    }
    if (ready_) {
        spare_ = std::move(ready_->planes);
        ready_.reset();
    }
    for (const auto& [dst, ref] : copies) std::copy(dest[ref], dest[ref] + N, dst);

    // Sums of products (Blender light passes times their colour passes), block by block; then
    // the block's absurd values replaced, in the sums and the channels they read (Deferred),
    // while it is in cache.
    std::vector<std::array<std::atomic<size_t>, 4>> compositeReplaced(composite.size());
    ctx.parallelRows(H, [&](int y0, int y1) {
        const size_t end = size_t(y1) * size_t(W);
        for (size_t b = size_t(y0) * size_t(W); b < end; b += kCompositeBlock) {
            const size_t e = std::min(end, b + kCompositeBlock);
            for (size_t k = 0; k < composite.size(); ++k) {
                const Recipe* r = composite[k];
                const ImageView& out = io.output(r->output);
                const int C = r->format == Format::Int32 ? 1 : channelCount(r->format);
                for (int c = 0; c < C; ++c) {
                    float* o = asFloats(out, c) + b;
                    std::fill(o, o + (e - b), 0.f);
                    for (const Term& t : r->terms) addTerm(t, dest, c, 1.f, o, b, e);
                    if (!r->cap.empty()) applyCap(r->cap, dest, c, o, b, e);
                    if (r == fastRest)
                        addPositiveRest(
                            asFloats(io.output("color"), c) + b,
                            asFloats(io.output("diffuse"), c) + b,
                            emissionBound ? asFloats(io.output("emission"), c) + b : nullptr, o,
                            e - b);
                    else if (r->rest)
                        addRest(*r->rest, dest, c, emissionBound || r->output == "emission", o, b,
                                e);
                }
            }
            for (size_t k = 0; k < composite.size(); ++k) {
                const Recipe* r = composite[k];
                const int C = r->format == Format::Int32 ? 1 : channelCount(r->format);
                for (int c = 0; c < C; ++c)
                    if (const size_t n = replaceAbsurd(asFloats(io.output(r->output), c) + b, e - b,
                                                       r->fill, r->lowest))
                        compositeReplaced[k][size_t(c)] += n;
            }
            for (const Deferred& d : deferred)
                if (!d.afterDerived) d.replace(b, e);
        }
    });
    // Positions unprojected from raw depth (before depth's own background convention).
    for (const Recipe* r : derived) {
        if (r->reflectionOf) continue;  // reflectionMask, below
        const float* depth = dest[r->terms[0][0][0]];
        if (r->output == "normal")
            normalsFromDepth(ctx, depth, r->rayLength, io.output(r->output), W, H);
        else
            unprojectDepth(ctx, depth, r->rayLength, io.output(r->output), W, H);
    }

    for (const Recipe* r : active)
        if (r->reflectionOf) reflectionMask(ctx, *r->reflectionOf, dest, io.output(r->output), N);
    // The depth a derived output was computed from: a pass of its own (renders without a
    // position or normal pass only).
    for (const Deferred& d : deferred)
        if (d.afterDerived)
            ctx.parallelRows(H, [&](int y0, int y1) {
                d.replace(size_t(y0) * size_t(W), size_t(y1) * size_t(W));
            });

    // Before the conventions (ids still floats): nothing non-finite or absurd leaves the loader.
    warnReplaced(replacedByOutput(ctx, io, active, composite, compositeReplaced, replaced, W, H));

    // Convention fixes, in place: scales (motion y), background depth, then ids to int32.
    for (const Recipe* r : active) {
        const ImageView& out = io.output(r->output);
        for (int c = 0; c < channelCount(r->format); ++c)
            if (r->scale[c] != 1.f && r->format != Format::Int32) {
                float* o = asFloats(out, c);
                const float s = r->scale[c];
                for (size_t i = 0; i < N; ++i) o[i] *= s;
            }
        if (r->backgroundMask) {
            const float* m = dest[*r->backgroundMask];
            float* o = asFloats(out, 0);
            for (size_t i = 0; i < N; ++i)
                if (!(m[i] > -0.5f)) o[i] = kBackgroundDepth;
        }
        if (r->zeroIsBackground) {
            float* o = asFloats(out, 0);
            for (size_t i = 0; i < N; ++i)
                if (!(o[i] > 0.f)) o[i] = kBackgroundDepth;
        }
        if (r->cameraSpace && ctx.scene && ctx.scene->hasCamera)
            rotateToWorld(ctx.scene->worldToCamera, out, N);
        if (r->zeroFallback) fillZeroVectors(*r->zeroFallback, dest, out, N);
    }
    for (const Recipe* r : active)
        if (r->skyDepth) skyMotion(ctx, dest[*r->skyDepth], io.output(r->output), W, H);
    for (const Recipe* r : active)
        if (r->format == Format::Int32)
            floatsToIds(asFloats(io.output(r->output), 0), N, r->idRule);

    if (!logged_) {
        std::string list;
        for (const auto& c : channelsRead_) list += (list.empty() ? "" : ", ") + c;
        // The count at the default level, the names with -v (38 names were ~900 characters).
        spdlog::info(
            "ExrLoader: reading {} channels per frame ({:.2f} MB decoded from {:.2f} MB "
            "of files)",
            channelsRead_.size(), double(channelsRead_.size() * N * 4) / 1e6,
            double(fileBytes) / 1e6);
        spdlog::debug("ExrLoader: channels read: {}", list);
        logged_ = true;
    }
    if (prefetch_) startPrefetch(frame_ + step_, fills, decodeFix);
}

}  // namespace kestrel::exr
