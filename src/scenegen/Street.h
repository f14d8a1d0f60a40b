#pragma once
// The street scenes (SceneOptions::Kind::Street and StreetNight): a street between two buildings
// under a gradient sky, built from axis-aligned boxes and spheres; its materials (Lambertian
// diffuse plus a normalised Phong lobe), lights and animation; ray intersection.
#include <vector>

#include "Scene.h"

namespace kestrel::scenegen {

// Object ids of the street (also the objectId AOV and the GAMES202 matrix order).
enum StreetId : int {
    kGround = 0,
    kLeftBuilding,
    kRightBuilding,
    kGoldSphere,
    kChromeSphere,
    kSign,
    kLampPost,
    kLampHead,
    kFence,
    kVan,
    kStreetObjectCount
};

/// Surface response at a point: diffuse albedo kd (Lambert) plus a Phong lobe of tint ks and
/// exponent `exponent` around the mirror direction; `emission` for emitters.
struct Material {
    V3 kd, ks;
    float exponent = 1.f;
    V3 emission;
};

struct StreetBox {  // axis-aligned, in world space at this frame
    V3 lo, hi;
    int id;
};

struct StreetState {
    Camera camera;
    Mat4 objectToWorld[kStreetObjectCount];
    Mat4 worldToObject[kStreetObjectCount];
    std::vector<StreetBox> boxes;  // buildings, sign, post, van, ground slab
    std::vector<StreetBox> fence;  // pickets and rail, tested only inside fenceBounds
    StreetBox fenceBounds{};
    std::vector<SphereObj> spheres;  // gold, chrome, lamp head
    V3 skyHorizon, skyZenith;        // sky radiance at the horizon and straight up
    bool sun = false;
    V3 sunDir, sunIrradiance;  // towards the sun, unit; irradiance normal to it
    V3 signRadiance;
    V3 lampCenter, lampRadiance;
    float lampRadius = 0.f;
    V3 vanPos;
};

/// The street at `frame` (any integer, also firstFrame - 1 for motion vectors).
StreetState makeStreet(const SceneOptions& options, int frame);

/// Closest hit with t in (0, tMax); hit.normal is the outward geometric normal.
bool intersectStreet(const StreetState& s, const Ray& r, float tMax, Hit& hit);
/// Any hit with t in (0, tMax).
bool occludedStreet(const StreetState& s, const Ray& r, float tMax);

/// Material at a hit point p (textures: brick paving, window grids, the van's windows).
Material materialAt(const StreetState& s, const Hit& hit, V3 p);
/// Radiance of the sky seen in direction d (noise-free, smooth gradient).
V3 skyRadiance(const StreetState& s, V3 d);

}  // namespace kestrel::scenegen
