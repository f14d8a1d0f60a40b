#pragma once
// The analytic scene: a room open at the front (+Z), two rotated boxes, three spheres (one
// sliding, one glowing) and a rectangular ceiling light; its animation; ray intersection.
#include "VecMath.h"

namespace kestrel::scenegen {

// Object ids (also the objectId AOV and the GAMES202 matrix order).
enum ObjectId : int {
    kFloor = 0,
    kCeiling,
    kBackWall,
    kLeftWall,
    kRightWall,
    kTallBox,
    kShortBox,
    kBigSphere,
    kMovingSphere,
    kGlowSphere,
    kAreaLight,
    kObjectCount
};

struct Camera {
    V3 pos;
    Mat4 cameraToWorld, worldToCamera, projection, worldToPixel;
    float tanX = 0, tanY = 0;  // tan of the half field of view
    int width = 0, height = 0;
    float nearPlane = 0.01f, farPlane = 100.f;
};

struct Ray {
    V3 o, d, invD;
};
inline Ray makeRay(V3 o, V3 d) {
    // Division guarded: an axis-parallel direction gives a huge (not infinite) inverse.
    auto inv = [](float v) { return 1.f / (std::fabs(v) > 1e-20f ? v : 1e-20f); };
    return {o, d, {inv(d.x), inv(d.y), inv(d.z)}};
}

struct Hit {
    float t = 0;
    int id = -1;
    V3 normal;  // world, unit, geometric (facing away from the surface's outside)
    V3 local;   // hit point in object space (textures)
};

struct AxisQuad {  // axis-aligned rectangle: coordinate `c` on axis `axis`
    int axis, ua, va;
    float c, u0, u1, v0, v1;
    V3 normal;
    int id;
};
struct SphereObj {
    V3 center;
    float radius;
    int id;
};
/// The nearest hit in (0, tMax) of a ray with a sphere, into t.
bool hitSphere(const SphereObj& sp, const Ray& r, float tMax, float& t);

struct BoxObj {
    Mat4 toWorld, toLocal;
    V3 half;
    int id;
    V3 lo, hi;  // world-space bounds
};

struct SceneState {
    Camera camera;
    Mat4 objectToWorld[kObjectCount];
    Mat4 worldToObject[kObjectCount];
    AxisQuad quads[6];  // floor, ceiling, 3 walls, the light
    SphereObj spheres[3];
    BoxObj boxes[2];
    // Emitters (next-event estimation).
    float lightY, lightX0, lightX1, lightZ0, lightZ1, lightArea;
    V3 lightRadiance;
    V3 glowCenter;
    float glowRadius;
    V3 glowRadiance;
};

/// A camera at `pos` looking at `target` (+Y up, vertical fov 50 degrees), with its matrices.
Camera lookAtCamera(V3 pos, V3 target, int width, int height);

/// The scene at `frame` (any integer, also firstFrame - 1 for motion vectors).
SceneState makeScene(const SceneOptions& options, int frame);

/// Closest hit with t in (0, tMax). `insideRoom`: the origin is inside the room (every ray but
/// the camera's), so the walls are found by one exit computation instead of five quad tests.
bool intersect(const SceneState& s, const Ray& r, float tMax, Hit& hit, bool insideRoom);
/// Any hit with t in (0, tMax) of a segment inside the room: the room is convex and the lights
/// are inside it, so only the boxes and spheres can occlude.
bool occluded(const SceneState& s, const Ray& r, float tMax);

/// Diffuse albedo at a hit (textures on the floor, the tall box and the moving sphere).
V3 albedoAt(const Hit& hit, V3 worldPos);
/// Emitted radiance towards direction -d at a hit (light: downward face only).
V3 emissionAt(const SceneState& s, const Hit& hit, V3 d);

}  // namespace kestrel::scenegen
