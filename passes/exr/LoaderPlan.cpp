// The loader's plan: which files a frame is (GAMES202 or one file per frame), which layout and
// view layer, and how each output is computed from the first frame's channels (ChannelPlan.h),
// adapted to what the render lacks; decided once, at compile time (resolve) or the first frame.
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>

#include "ExrLoader.h"
#include "KeepPasses.h"
#include "LoaderDecode.h"

namespace kestrel::exr {

namespace fs = std::filesystem;

namespace {

std::string parentDir(const std::string& p) {
    auto slash = p.rfind('/');
    return slash == std::string::npos ? std::string() : p.substr(0, slash + 1);
}

std::set<std::string> channelNames(const Imf::Header& h) {
    std::set<std::string> names;
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it) names.insert(it.name());
    return names;
}

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

void ExrLoader::ensurePlan(int64_t frame, Notes* notes) {
    if (planned_) return;
    if (p_.path.empty()) throw Error("ExrLoader: parameter 'path' is empty: give a frame pattern");
    Notes ignored;
    Notes& note = notes ? *notes : ignored;

    // Which files: a GAMES202 folder or beauty_ pattern, else one multi-channel file per frame.
    std::string pattern;
    bool namedLikeBeauty = false;
    bool games202 = choosePattern(pattern, namedLikeBeauty);
    const int64_t first = probedFrame(frame, pattern, note);
    const std::string firstPath = pattern_->expand(first);

    // A file merely named beauty.####.exr is a multi-channel frame unless GAMES202's other
    // buffers lie beside it (its normal_ or depth_ file for the same frame).
    std::error_code ec;
    if (namedLikeBeauty &&
        !fs::exists(FramePattern(games202Dir_ + "normal" + games202Tail_).expand(first), ec) &&
        !fs::exists(FramePattern(games202Dir_ + "depth" + games202Tail_).expand(first), ec)) {
        games202 = false;
        note.push_back(
            "named like GAMES202's beauty files, but no normal or depth file lies "
            "beside " +
            firstPath + ": one multi-channel file per frame");
    }

    ChannelSets sets;
    std::unique_ptr<ExrInput> probed;  // the first file (single-file layouts)
    if (games202)
        planGames202Files(first, firstPath, sets, note);
    else
        probed = planSingleFile(first, firstPath, sets, note);
    adaptPlan(probed.get(), first, sets, note);
    note.push_back(std::string("layout ") + layoutName(plan_.layout) + " (" + firstPath + ")");
    for (const auto& r : plan_.recipes)
        if (!r.absent) note.push_back(r.output + " = " + r.why);
    planned_ = true;
}

bool ExrLoader::choosePattern(std::string& pattern, bool& namedLikeBeauty) {
    const LayoutChoice layout = p_.layout;
    pattern = p_.path;
    std::error_code ec;
    bool games202 = layout == LayoutChoice::Games202;
    const bool folder = fs::is_directory(pattern, ec);
    if (folder) {
        std::string dir = pattern.back() == '/' ? pattern : pattern + "/";
        // Only GAMES202's layout is a folder of files per frame; any other folder is the
        // user's slip for a pattern, said with the pattern its files suggest.
        if ((layout != LayoutChoice::Auto && layout != LayoutChoice::Games202) ||
            (layout == LayoutChoice::Auto && !holdsGames202Beauty(dir)))
            throw Error(
                "path " + p_.path + " is a folder" +
                (layout == LayoutChoice::Auto ? " without GAMES202's beauty_N.exr files" : "") +
                ": give a frame pattern such as " + suggestedPattern(dir));
        pattern = dir + "beauty_%d.exr";
        games202 = true;
    }
    pattern_ = std::make_unique<FramePattern>(pattern);
    std::string file = pattern.substr(parentDir(pattern).size());
    namedLikeBeauty = layout == LayoutChoice::Auto && !folder && file.rfind("beauty", 0) == 0;
    if (namedLikeBeauty) games202 = true;
    if (games202) {
        if (file.rfind("beauty", 0) != 0)
            throw Error("layout games202: path " + p_.path +
                        " must be a folder or name the beauty files (dir/beauty_%d.exr)");
        games202Dir_ = parentDir(pattern);
        games202Tail_ = file.substr(6);
    }
    return games202;
}

int64_t ExrLoader::probedFrame(int64_t frame, const std::string& pattern, Notes& note) const {
    // First frame: the requested one, else the first found on disk.
    const std::string firstPath = pattern_->expand(frame);
    std::error_code ec;
    if (fs::exists(firstPath, ec)) return frame;
    auto found = pattern_->findFrames();
    if (found.empty())
        throw Error("no input frame: " + firstPath + " does not exist and nothing matches " +
                    pattern);
    note.push_back("frame " + std::to_string(frame) + " missing; layout probed on frame " +
                   std::to_string(found.front()));
    return found.front();
}

void ExrLoader::planGames202Files(int64_t first, const std::string& firstPath, ChannelSets& sets,
                                  Notes& note) {
    std::error_code ec;
    plan_.layout = Layout::Games202;
    for (const char* role : kGames202Roles) {
        std::string p = filePath(role, first);
        if (!fs::exists(p, ec)) continue;
        try {
            ExrInput in(p, p_.maxPixels);
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
    note.push_back(games202Matrices_ ? "camera and object matrices from " + mat
                                     : "no matrix file " + mat + ": no camera matrices");
}

std::unique_ptr<ExrInput> ExrLoader::planSingleFile(int64_t first, const std::string& firstPath,
                                                    ChannelSets& sets, Notes& note) {
    std::unique_ptr<ExrInput> in;
    try {
        in = std::make_unique<ExrInput>(firstPath, p_.maxPixels);
    } catch (const Error& e) {
        throw Error(firstPath + ": " + e.what());
    }
    sets[""] = channelNames(in->header());
    rememberFirstFrame(first, *in);
    const auto layers = blenderLayers(sets[""]);
    const auto* tag = in->header().findTypedAttribute<Imf::StringAttribute>("kestrel.layout");
    if (p_.layout == LayoutChoice::Blender ||
        (p_.layout == LayoutChoice::Auto && !tag && !layers.empty())) {
        planBlenderFile(firstPath, layers, sets, note);
        return in;
    }
    if (!p_.layer.empty())  // a layer choice that would silently do nothing
        throw Error("layer '" + p_.layer + "': " + firstPath +
                    " is not a Blender multilayer EXR (layout canonical): it has no view layers");
    plan_ = planCanonical(sets);
    if (!tag)
        note.push_back("no kestrel.layout attribute: reading canonical channel names");
    else if (tag->value() != "canonical")
        throw Error(firstPath + ": kestrel.layout is '" + tag->value() +
                    "', this loader reads 'canonical'");
    return in;
}

void ExrLoader::planBlenderFile(const std::string& firstPath,
                                const std::vector<std::string>& layers, const ChannelSets& sets,
                                Notes& note) {
    const auto layer = chooseLayer(layers, p_.layer, firstPath);
    if (!layer)
        throw Error("layout blender: " + firstPath +
                    " has no '<layer>.Combined.R' channel (not a Cycles multilayer EXR)");
    note.push_back("Blender view layer '" + *layer + "'");
    // camera.json: the parameter, else beside the frames, else one folder up.
    std::error_code ec;
    fs::path cam = p_.camera;
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
        note.push_back("cameras from " + cam.string());
    } else {
        note.push_back("no camera.json beside the frames or one folder up: no camera matrices");
        if (plan_.find("normal")->cameraSpace)
            note.push_back(
                "normal: Denoising Normal stays in camera space (no camera to rotate it by)");
    }
}

void ExrLoader::adaptPlan(ExrInput* probed, int64_t first, const ChannelSets& sets, Notes& note) {
    std::set<std::string> overridden;
    if (!p_.channels.empty()) overridden = applyChannelOverrides(plan_, p_.channels, sets);
    for (const char* o : {"color", "diffuse", "specular", "emission"})
        if (overridden.count(o)) {
            addSplitRest(plan_, overridden);
            break;
        }
    planAntiAliasing(probed, overridden);
    note.push_back(antiAliasing_.why);  // the decision, once per run, with why (PixelJitter.h)
    colorHalf_ = storedAsHalf("color", probed, first);
    depthHalf_ = storedAsHalf("depth", probed, first);
    if (!overridden.count("position")) planPositionFromDepth(probed);
    if (!overridden.count("normal")) planNormalFromDepth(probed);
    if (Recipe& reflection = *plan_.find("reflection");
        reflection.reflectionOf && !hasCamera(probed)) {
        reflection.reflectionOf.reset();
        reflection.absent = true;
        reflection.why = "no camera (camera.json) to turn Denoising Normal to world space";
    }
    if (!overridden.count("motion")) planSkyMotion();
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
                    other = std::make_unique<ExrInput>(filePath(ref.file, frame), p_.maxPixels);
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
    // Without a camera they are reconstructed in camera space from an assumed field of view
    // (normalsFromDepth says why that is enough for the filters).
    if (!normal.absent || depth.absent || !depth.isDirect()) return;
    const std::string missing = normal.why;
    normal.terms = {{{depth.terms[0][0][0]}}};
    normal.fromDepth = true;
    normal.rayLength = depth.zeroIsBackground;  // Denoising Depth: distance along the ray
    normal.cameraSpace = normal.zeroIsBackground = false;
    normal.absent = false;
    const std::string camera =
        hasCamera(first)
            ? (cameras_ ? cameras_->path().filename().string() : "the file's camera")
            : "no camera: in camera space, for Blender's default 50 mm lens (" +
                  std::to_string(int(std::lround(kAssumedFieldOfView))) +
                  " degrees across); the camera parameter (camera.json) gives world space";
    normal.why = "reconstructed from " + depth.terms[0][0][0].str() + " with " + camera +
                 " (geometric normals, no bump or smoothing; " + missing + ")";
}

void ExrLoader::planAntiAliasing(ExrInput* first, const std::set<std::string>& overridden) {
    if (p_.antiAliased != AntiAliasedChoice::Auto) {
        const bool on = p_.antiAliased == AntiAliasedChoice::True;
        antiAliasing_ = {on, std::string("antiAliased parameter ") + (on ? "true" : "false")};
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
        if (r.absent) rc.setAbsent(port(&r), r.why);
}

}  // namespace kestrel::exr
