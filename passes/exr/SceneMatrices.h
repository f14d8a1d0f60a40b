#pragma once
// Per-frame camera and object matrices from the files beside the frames: Blender's camera.json
// (data/README.md) and GAMES202's matrix_i.mat.
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>

#include "kestrel/FrameContext.h"

namespace kestrel::exr {

/// Blender camera.json, parsed once. Throws Error naming the file if it is unreadable.
class BlenderCameras {
public:
    explicit BlenderCameras(const std::filesystem::path& file);
    /// Fills scene for `frame`; false when the file lists no such frame.
    bool fill(int64_t frame, SceneData& scene) const;
    bool has(int64_t frame) const { return frames_.count(frame) > 0; }
    const std::filesystem::path& path() const { return path_; }
    /// The pixel filter width its render settings state, if they do.
    std::optional<float> pixelFilterWidth() const { return pixelFilterWidth_; }

private:
    std::filesystem::path path_;
    std::optional<float> pixelFilterWidth_;
    std::map<int64_t, SceneData> frames_;
};

/// Reads a GAMES202 matrix file into scene (objectToWorld per id, worldToCamera, worldToPixel).
/// worldToCamera is converted to SceneData's OpenGL convention (camera looks down -z).
/// Throws Error with the reason (short file, absurd count).
void readGames202Matrices(const std::filesystem::path& file, SceneData& scene);

/// Blender's pixel mapping folded into a matrix: px = (ndc.x + 1)/2 W, py = (1 - ndc.y)/2 H.
Mat4 ndcToPixel(int width, int height);

/// Field of view (degrees) across the image's width of the camera a render without one is taken
/// to have: Blender's default, a 50 mm lens on a 36 mm sensor (Blender fits the sensor to the
/// longer side, so for a portrait render this is its height's: the normals then lean more).
constexpr double kAssumedFieldOfView = 39.5977;

/// Camera space to pixels for a perspective camera of `fieldOfView` horizontal degrees on a
/// width x height image (square pixels; OpenGL camera space, looking down -z).
Mat4 perspectiveToPixel(double fieldOfView, int width, int height);

}  // namespace kestrel::exr
