#pragma once
// Procedural test scenes: a small analytic room (the default) or an outdoor street, path-traced on
// the CPU at 1 spp with every AOV the Kestrel passes consume, plus a many-spp reference, written
// as EXR sequences (docs/canonical-layout.md). zooScenes() names a set of configurations that
// together cover what real content has (sky, fine texture, glossy and mirror surfaces, emitters,
// thin geometry, disocclusion, fireflies, a camera cut, a jittered pixel filter). Deterministic:
// the output depends only on the options, never on the thread count. Of the Kestrel framework it
// uses only the matrix type (kestrel/Math.h).
#include <kestrel/Math.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace kestrel::scenegen {

/// The engine's matrix (row-major m[row][col], column-vector convention p' = M (x, y, z, 1)^T):
/// the scenes' cameras and objects go to the loader's FrameContext as they are.
using Mat4 = kestrel::Mat4;

struct SceneOptions {
    /// Room: the interior (default; its output never changes). Street: outdoor, sky + sun, brick
    /// paving, glossy gold and mirror spheres, emitters, thin poles and fence, a van crossing.
    /// StreetNight: the street at night (dim sky, no sun), lit by a small intense lamp that the
    /// 1-spp frames only find by BSDF sampling: fireflies.
    enum class Kind { Room, Street, StreetNight } kind = Kind::Room;
    int width = 160, height = 90;
    int frames = 8;
    int firstFrame = 1;
    int referenceSpp = 64;
    uint32_t seed = 1;
    bool staticCamera = false;  ///< camera frozen at its frame-1 pose
    bool movingObject = true;   ///< the sliding sphere moves (else frozen at its frame-1 place)
    int cameraCutFrame = -1;    ///< from this frame on the camera jumps to a second viewpoint
    /// From this frame on the street's lights, the sun and the lamp (its visible head too), shine
    /// at lightChangeScale of their strength: a cloud, a light switched off (a scale > 1:
    /// switched on); the sky is unchanged. The geometry does not change, so only the lighting says
    /// the history is stale. -1: no change. Street kinds only.
    int lightChangeFrame = -1;
    float lightChangeScale = 0.2f;
    /// Room only: the ceiling light swings along x by up to this many metres (its centre at
    /// lightSwing * sin(0.35 (frame - 1))): a lamp whose pool and shadows move. 0: still.
    float lightSwing = 0.f;
    /// Surface interactions per path, each with next-event estimation: 1 = direct light only,
    /// 2 = direct + one indirect bounce (the default), 3 = two indirect bounces.
    int bounces = 2;
    int threads = 0;  ///< 0: hardware concurrency; the result never depends on it
    /// Width in pixels of a Blackman-Harris pixel filter (Blender's default is 1.5). 0: every
    /// primary ray through the pixel centre. > 0: each 1-spp frame's primary ray goes through a
    /// random point of the filter footprint (every G-buffer AOV is that one sample) and the
    /// reference is the filtered average (anti-aliased). Street kinds only.
    float pixelFilterWidth = 0.f;
    /// Scale of every written light AOV (color, emission, direct, indirect, diffuse, specular)
    /// and of the reference: a render's radiance units are its own (a physically based sun
    /// can be 1000x the zoo's), and a denoiser's result should not depend on them.
    float exposure = 1.f;
    /// AOVs left out of the files: albedo, emission, direct, indirect, diffuse, diffuseAlbedo,
    /// specular, specularAlbedo, normal, depth, position, motion, objectId, camera (the matrices).
    /// Unknown names are rejected by writeSequence.
    std::set<std::string> omit;
    enum class Layout { Canonical, Games202 } layout = Layout::Canonical;
};

/// One 1-spp frame with its G-buffer, in the in-memory conventions of kestrel/Conventions.h.
/// Images are planar: channel c of pixel (x, y) (y = 0 is the top row) at [c][y * width + x].
struct FrameAovs {
    int width = 0, height = 0, frame = 0;
    std::array<std::vector<float>, 3> color;     ///< direct + indirect + emission (sky)
    std::array<std::vector<float>, 3> albedo;    ///< first-hit diffuse albedo; 0 on background
    std::array<std::vector<float>, 3> emission;  ///< first-hit emitted radiance; sky radiance
    std::array<std::vector<float>, 3> direct;    ///< NEE at the first hit (radiance)
    std::array<std::vector<float>, 3> indirect;  ///< everything after the first bounce
    /// Diffuse / specular split (Blender's convention): diffuse = diffuseIllum * diffuseAlbedo,
    /// specular = specularIllum * specularAlbedo, color = diffuse + specular + emission.
    std::array<std::vector<float>, 3> diffuse;
    std::array<std::vector<float>, 3> diffuseAlbedo;  ///< = albedo
    std::array<std::vector<float>, 3> specular;
    std::array<std::vector<float>, 3> specularAlbedo;  ///< specular tint; 0 without a lobe
    std::array<std::vector<float>, 3> normal;          ///< world, unit, facing the camera; 0 on bg
    std::array<std::vector<float>, 3> position;        ///< world; 0 on background
    std::vector<float> depth;                          ///< linear view depth; 1e10 on background
    std::array<std::vector<float>, 2> motion;          ///< pixels to frame-1, x right, y down
    std::vector<int32_t> objectId;                     ///< -1 on background
    Mat4 worldToCamera{};                              ///< OpenGL view: camera looks down -Z, +Y up
    Mat4 projection{};    ///< OpenGL clip-from-camera (ndc in [-1, 1]) from the vertical fov
    Mat4 worldToPixel{};  ///< after the divide: pixel coords, x right, y down, centres at +0.5
    Mat4 cameraToWorld{};
    std::map<int, Mat4> objectToWorld;  ///< every object id of the scene (0..N-1)
};

/// Renders frame `frame` at 1 spp with every AOV.
FrameAovs renderFrame(const SceneOptions& options, int frame);
/// Renders the reference of `frame` (options.referenceSpp samples): RGB planar, 3 * w * h floats
/// (R plane, G plane, B plane). Same primary rays (the same filter distribution) as renderFrame,
/// other random numbers: it is the expectation of the 1-spp frames. Same estimator too, except
/// that the street's lamp is also sampled directly (the 1-spp frames only reach it by BSDF
/// sampling: fireflies), which changes the variance, not the expectation.
std::vector<float> renderReference(const SceneOptions& options, int frame);
/// Number of objects (ids 0..N-1) of the room scene.
int objectCount();
/// Number of objects (ids 0..N-1) of the scene options.kind selects.
int objectCount(const SceneOptions& options);

/// A named configuration of the scene zoo.
struct ZooScene {
    std::string name;
    SceneOptions options;
    std::string description;  ///< what it covers
};
/// The zoo: every scene at its intended size (96x64, 12 frames, 256-spp references).
std::vector<ZooScene> zooScenes();
/// The zoo scene called `name`; throws std::invalid_argument naming the known ones otherwise.
ZooScene zooScene(const std::string& name);

struct WriteStats {
    double seconds = 0;
    int filesWritten = 0;
    int framesWritten = 0;
};
/// Called after each frame: (frames done, frames total).
using ProgressFn = std::function<void(int, int)>;
/// Writes the sequence (noisy frames + references) into `dir` in options.layout. Prints nothing.
/// Throws std::invalid_argument for bad options, std::runtime_error on I/O errors. Each file is
/// written to a temporary name then renamed, so no partial file is left behind.
WriteStats writeSequence(const SceneOptions& options, const std::filesystem::path& dir,
                         const ProgressFn& progress = {});

}  // namespace kestrel::scenegen
