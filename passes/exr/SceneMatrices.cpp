#include "SceneMatrices.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>
#include <vector>

#include "kestrel/Error.h"
#include "kestrel/InputFiles.h"
#include "kestrel/Math.h"

namespace kestrel::exr {

namespace fs = std::filesystem;

// camera.json of a 10,000-frame shot with its objects is a few MB; a GAMES202 .mat is 64 bytes
// a matrix. Far larger is the wrong file.
constexpr std::uintmax_t kMaxSidecarBytes = 256u << 20;

Mat4 ndcToPixel(int width, int height) {
    // Applied to clip coordinates before the divide: x' = W/2 x + W/2 w, y' = -H/2 y + H/2 w.
    Mat4 v = Mat4::identity();
    v.m[0][0] = 0.5f * float(width);
    v.m[0][3] = 0.5f * float(width);
    v.m[1][1] = -0.5f * float(height);
    v.m[1][3] = 0.5f * float(height);
    return v;
}

Mat4 perspectiveToPixel(double fieldOfView, int width, int height) {
    const double tanX = std::tan(fieldOfView * 0.5 * 3.14159265358979323846 / 180.0),
                 tanY = tanX * double(height) / double(std::max(width, 1));
    Mat4 p;
    p.m[0][0] = float(1.0 / tanX);
    p.m[1][1] = float(1.0 / tanY);
    p.m[2][2] = -1.f;  // depth is not read from it (pointOnPixelRay uses rows 0, 1 and 3)
    p.m[3][2] = -1.f;  // w = -z: the distance in front of the camera
    return ndcToPixel(width, height) * p;
}

namespace {
// The bound of the loader's absurd input values (docs/errors.md): a matrix entry beyond it
// (1e308 became inf as a float) places no camera or object anywhere.
constexpr double kAbsurd = 1e30;

/// `key` of one frame's entry; throws Error naming the key when it is not a 4x4 matrix of
/// finite, not absurd numbers, or (`invertible`) when it has no inverse (all zero): a camera
/// matrix without an inverse turns every pixel's position, normal and motion into NaN or 0.
Mat4 toMat(const nlohmann::json& frame, const std::string& key, bool invertible) {
    const nlohmann::json& j = frame.at(key);
    Mat4 m;
    if (!j.is_array() || j.size() != 4) throw Error(key + " is not a 4x4 nested list");
    for (int r = 0; r < 4; ++r) {
        if (!j[r].is_array() || j[r].size() != 4) throw Error(key + ": a row has not 4 entries");
        for (int c = 0; c < 4; ++c) {
            const double v = j[r][c].get<double>();
            if (!std::isfinite(v) || std::fabs(v) > kAbsurd)
                throw Error(key + "[" + std::to_string(r) + "][" + std::to_string(c) + "] is " +
                            nlohmann::json(v).dump() + " (non-finite or |v| > 1e30)");
            m.m[r][c] = float(v);
        }
    }
    if (invertible && !inverse(m)) throw Error(key + " has no inverse (all zero?)");
    return m;
}
}  // namespace

namespace {
/// render_settings.filter_width_px, else the width in its pixel_filter text ("BLACKMAN_HARRIS,
/// width 1.5 px"); nullopt when the file does not say.
std::optional<float> statedFilterWidth(const nlohmann::json& j) {
    if (!j.contains("render_settings") || !j["render_settings"].is_object()) return std::nullopt;
    const auto& r = j["render_settings"];
    if (r.contains("filter_width_px") && r["filter_width_px"].is_number())
        return std::max(0.f, r["filter_width_px"].get<float>());
    if (r.contains("pixel_filter") && r["pixel_filter"].is_string()) {
        const std::string t = r["pixel_filter"].get<std::string>();
        const auto at = t.find("width ");
        if (at != std::string::npos) {
            try {
                return std::max(0.f, std::stof(t.substr(at + 6)));
            } catch (const std::exception&) {
            }
        }
    }
    return std::nullopt;
}
}  // namespace

namespace {
SceneData frameEntry(const nlohmann::json& f, const Mat4& viewport,
                     const std::map<std::string, int32_t>& ids) {
    SceneData s;
    s.hasCamera = true;
    s.worldToCamera = toMat(f, "view", true);
    s.worldToPixel = viewport * toMat(f, "view_projection", true);
    if (f.contains("objects"))
        for (const auto& [name, m] : f["objects"].items())
            if (auto it = ids.find(name); it != ids.end())
                s.objectToWorld[it->second] =
                    toMat(f["objects"], name, false);  // scale 0 hides one
    return s;
}
}  // namespace

BlenderCameras::BlenderCameras(const fs::path& file) : path_(file) {
    const std::string text = readRegularFile(file, "camera file", kMaxSidecarBytes);
    checkJsonText(text, file.string());
    try {
        nlohmann::json j = nlohmann::json::parse(text);
        int w = j.at("resolution").at(0).get<int>(), h = j.at("resolution").at(1).get<int>();
        Mat4 viewport = ndcToPixel(w, h);
        std::map<std::string, int32_t> ids;
        if (j.contains("object_pass_index"))
            for (const auto& [name, id] : j["object_pass_index"].items())
                ids[name] = id.get<int32_t>();
        pixelFilterWidth_ = statedFilterWidth(j);
        for (const auto& f : j.at("frames")) {
            const int64_t frame = f.at("frame").get<int64_t>();
            try {
                frames_[frame] = frameEntry(f, viewport, ids);
            } catch (const std::exception& e) {
                throw Error("frame " + std::to_string(frame) + ": " + e.what());
            }
        }
    } catch (const Error& e) {
        throw Error("camera file " + file.string() + ": " + e.what());
    } catch (const std::exception& e) {
        throw Error("camera file " + file.string() + ": " + e.what());
    }
}

bool BlenderCameras::fill(int64_t frame, SceneData& scene) const {
    auto it = frames_.find(frame);
    if (it == frames_.end()) return false;
    scene = it->second;
    return true;
}

void readGames202Matrices(const fs::path& file, SceneData& scene) {
    const std::string bytes = readRegularFile(file, "matrix file", kMaxSidecarBytes);
    auto readInt = [&](size_t at) {
        uint32_t v = uint32_t(uint8_t(bytes[at])) | uint32_t(uint8_t(bytes[at + 1])) << 8 |
                     uint32_t(uint8_t(bytes[at + 2])) << 16 |
                     uint32_t(uint8_t(bytes[at + 3])) << 24;
        return v;
    };
    if (bytes.size() < 4) throw Error("too short for a matrix count");
    int32_t n = int32_t(readInt(0));
    // little-endian int32 N, then N+2 row-major float32 4x4 matrices (data/README.md)
    if (n < 0 || uint64_t(n) + 2 > (bytes.size() - 4) / 64 ||
        4 + (uint64_t(n) + 2) * 64 != bytes.size())
        throw Error("size " + std::to_string(bytes.size()) + " does not match its count " +
                    std::to_string(n) + " (expected 4 + (N+2)*64 bytes)");
    auto mat = [&](int k) {
        Mat4 m;
        for (int i = 0; i < 16; ++i) {
            uint32_t u = readInt(4 + size_t(k) * 64 + size_t(i) * 4);
            float f;
            std::memcpy(&f, &u, 4);
            m.m[i / 4][i % 4] = f;
        }
        return m;
    };
    scene = SceneData{};
    for (int i = 0; i < n; ++i) scene.objectToWorld[i] = mat(i);
    // The file's camera space looks down +z (x right, y up); SceneData's is OpenGL's (down -z):
    // negate the z row so that depth = -z_camera for every layout.
    scene.worldToCamera = mat(n);
    for (int c = 0; c < 4; ++c) scene.worldToCamera.m[2][c] = -scene.worldToCamera.m[2][c];
    scene.worldToPixel = mat(n + 1);
    scene.hasCamera = true;
}

}  // namespace kestrel::exr
