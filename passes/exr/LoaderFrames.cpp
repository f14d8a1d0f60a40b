// The loader's files and frames: the files of a frame, the frames on disk, the run's checks
// (camera entries, every frame the first's size), and each frame's header and scene.
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfThreading.h>

#include <filesystem>

#include "ExrLoader.h"

namespace kestrel::exr {

namespace fs = std::filesystem;

namespace {

Mat4 toMat4(const Imath::M44f& x) {
    Mat4 m;
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) m.m[r][c] = x[r][c];
    return m;
}

}  // namespace

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
    if (p_.path.empty()) return {};
    std::string p = p_.path;
    std::error_code ec;
    if (fs::is_directory(p, ec)) p = (fs::path(p) / "beauty_%d.exr").string();
    try {
        return FramePattern(p).findFrames();
    } catch (const Error&) {
        return {};
    }
}

ExrInput& ExrLoader::openRole(const std::string& role, int64_t frame) {
    for (auto& [r, in] : open_)
        if (r == role) return *in;
    std::string p = filePath(role, frame);
    try {
        auto in = std::make_unique<ExrInput>(p, p_.maxPixels);
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

}  // namespace kestrel::exr
