// writeSequence: the canonical and GAMES202 file layouts (docs/canonical-layout.md).
#include <chrono>
#include <cstdio>
#include <stdexcept>

#include "ExrFile.h"
#include "Games202.h"
#include "scenegen/SceneGen.h"

namespace kestrel::scenegen {

namespace fs = std::filesystem;

namespace {

const std::set<std::string> kOmittable = {"color",          "albedo",   "emission",      "direct",
                                          "indirect",       "diffuse",  "diffuseAlbedo", "specular",
                                          "specularAlbedo", "normal",   "depth",         "position",
                                          "motion",         "objectId", "camera"};

std::string numbered(const char* pattern, int frame) {
    char buf[64];
    std::snprintf(buf, sizeof buf, pattern, frame);
    return buf;
}

ExrAttributes canonicalAttributes(const FrameAovs* f, bool withCamera) {
    ExrAttributes a;
    a.strings.emplace_back("kestrel.layout", "canonical");
    a.ints.emplace_back("kestrel.layoutVersion", 1);
    if (!f) return a;
    a.ints.emplace_back("kestrel.frame", f->frame);
    if (!withCamera) return a;
    a.matrices.push_back({"kestrel.worldToCamera", f->worldToCamera});
    a.matrices.push_back({"kestrel.projection", f->projection});
    a.matrices.push_back({"kestrel.worldToPixel", f->worldToPixel});
    for (const auto& [id, m] : f->objectToWorld)
        a.matrices.push_back({"kestrel.objectToWorld." + std::to_string(id), m});
    return a;
}

class Writer {
public:
    Writer(const SceneOptions& o, const fs::path& dir) : o_(o), dir_(dir) {}
    int files = 0;

    bool keep(const char* aov) const { return !o_.omit.count(aov); }

    void canonical(int frame) {
        const FrameAovs f = exposed(renderFrame(o_, frame));
        std::vector<float> ids(f.objectId.begin(), f.objectId.end());
        std::vector<ExrChannel> ch;
        auto add3 = [&](const char* aov, const std::array<std::vector<float>, 3>& img,
                        const char* prefix, const char* comps) {
            if (!keep(aov)) return;
            for (int c = 0; c < 3; ++c)
                ch.push_back({std::string(prefix) + comps[c], img[size_t(c)].data()});
        };
        add3("color", f.color, "", "RGB");
        add3("albedo", f.albedo, "albedo.", "RGB");
        add3("emission", f.emission, "emission.", "RGB");
        add3("direct", f.direct, "direct.", "RGB");
        add3("indirect", f.indirect, "indirect.", "RGB");
        // The room is Lambertian (specular 0): its files keep the channels they always had.
        if (o_.kind != SceneOptions::Kind::Room) {
            add3("diffuse", f.diffuse, "diffuse.", "RGB");
            add3("diffuseAlbedo", f.diffuseAlbedo, "diffuseAlbedo.", "RGB");
            add3("specular", f.specular, "specular.", "RGB");
            add3("specularAlbedo", f.specularAlbedo, "specularAlbedo.", "RGB");
        }
        add3("normal", f.normal, "normal.", "XYZ");
        if (keep("depth")) ch.push_back({"depth.Z", f.depth.data()});
        add3("position", f.position, "position.", "XYZ");
        if (keep("motion")) {
            ch.push_back({"motion.X", f.motion[0].data()});
            ch.push_back({"motion.Y", f.motion[1].data()});
        }
        if (keep("objectId")) ch.push_back({"objectId.id", ids.data()});
        const ExrAttributes attrs = canonicalAttributes(&f, keep("camera"));
        writeExr(dir_ / "noisy" / numbered("frame_%04d.exr", frame), f.width, f.height, ch, attrs);
        ++files;

        const std::vector<float> ref = exposed(renderReference(o_, frame));
        const size_t n = size_t(f.width) * size_t(f.height);
        writeExr(dir_ / "ref" / numbered("frame_%04d.exr", frame), f.width, f.height,
                 {{"R", ref.data()}, {"G", ref.data() + n}, {"B", ref.data() + 2 * n}}, attrs);
        ++files;
    }

    void games202(int frame) {
        const FrameAovs f = exposed(renderFrame(o_, frame));
        const int w = f.width, h = f.height;
        const size_t n = size_t(w) * size_t(h);
        auto rgb = [&](const char* stem, const std::array<std::vector<float>, 3>& img) {
            writeExr(dir_ / numbered(stem, frame), w, h,
                     {{"R", img[0].data()}, {"G", img[1].data()}, {"B", img[2].data()}});
            ++files;
        };
        if (keep("color")) rgb("beauty_%d.exr", f.color);
        if (keep("normal")) rgb("normal_%d.exr", f.normal);
        if (keep("position")) {
            // The homework stores the camera position on background pixels.
            std::array<std::vector<float>, 3> pos = f.position;
            const auto& c2w = f.cameraToWorld.m;
            const float cam[3] = {c2w[0][3], c2w[1][3], c2w[2][3]};
            for (size_t k = 0; k < n; ++k)
                if (f.objectId[k] < 0)
                    for (int c = 0; c < 3; ++c) pos[size_t(c)][k] = cam[c];
            rgb("position_%d.exr", pos);
        }
        if (keep("depth")) {
            std::vector<float> z(f.depth);
            for (size_t k = 0; k < n; ++k)
                if (f.objectId[k] < 0) z[k] = 0.f;  // homework: 0 on background
            writeExr(dir_ / numbered("depth_%d.exr", frame), w, h, {{"Y", z.data()}});
            ++files;
        }
        if (keep("objectId")) {
            std::vector<float> ids(f.objectId.begin(), f.objectId.end());
            writeExr(dir_ / numbered("ID_%d.exr", frame), w, h, {{"Y", ids.data()}});
            ++files;
        }
        if (keep("camera")) {
            writeFileAtomic(dir_ / numbered("matrix_%d.mat", frame), games202MatrixFile(f));
            ++files;
        }
        const std::vector<float> ref = exposed(renderReference(o_, frame));
        writeExr(dir_ / "reference" / numbered("beauty_%d.exr", frame), w, h,
                 {{"R", ref.data()}, {"G", ref.data() + n}, {"B", ref.data() + 2 * n}});
        ++files;
    }

private:
    /// The light scaled by SceneOptions::exposure.
    std::vector<float> exposed(std::vector<float> v) const {
        if (o_.exposure != 1.f)
            for (float& x : v) x *= o_.exposure;
        return v;
    }
    FrameAovs exposed(FrameAovs f) const {
        for (auto* img : {&f.color, &f.emission, &f.direct, &f.indirect, &f.diffuse, &f.specular})
            for (auto& plane : *img) plane = exposed(std::move(plane));
        return f;
    }

    const SceneOptions& o_;
    fs::path dir_;
};

void makeDir(const fs::path& p) {
    std::error_code ec;
    fs::create_directories(p, ec);
    if (ec) throw std::runtime_error("scenegen: cannot create " + p.string() + ": " + ec.message());
}

}  // namespace

WriteStats writeSequence(const SceneOptions& options, const fs::path& dir,
                         const ProgressFn& progress) {
    const auto start = std::chrono::steady_clock::now();
    for (const auto& name : options.omit)
        if (!kOmittable.count(name))
            throw std::invalid_argument("scenegen: unknown AOV '" + name +
                                        "' in omit (known: color, albedo, emission, direct, "
                                        "indirect, diffuse, diffuseAlbedo, specular, "
                                        "specularAlbedo, normal, depth, position, motion, "
                                        "objectId, camera)");
    if (options.frames < 1) throw std::invalid_argument("scenegen: frames must be >= 1");
    if (!(options.exposure > 0.f && options.exposure <= 1e9f))
        throw std::invalid_argument("scenegen: exposure must be in (0, 1e9]");
    const bool games = options.layout == SceneOptions::Layout::Games202;
    if (games) {
        makeDir(dir / "reference");
    } else {
        makeDir(dir / "noisy");
        makeDir(dir / "ref");
    }
    Writer writer(options, dir);
    WriteStats stats;
    for (int k = 0; k < options.frames; ++k) {
        const int frame = options.firstFrame + k;
        if (games)
            writer.games202(frame);
        else
            writer.canonical(frame);
        ++stats.framesWritten;
        if (progress) progress(k + 1, options.frames);
    }
    stats.filesWritten = writer.files;
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return stats;
}

}  // namespace kestrel::scenegen
