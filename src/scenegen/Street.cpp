#include "Street.h"

#include <algorithm>

#include "Random.h"

namespace kestrel::scenegen {

namespace {

using Kind = SceneOptions::Kind;

V3 lerp(V3 a, V3 b, float t) {
    return a * (1.f - t) + b * t;
}
float fract(float v) {
    return v - std::floor(v);
}

// Entry distance of a ray into an axis-aligned box and the axis of the face it enters through;
// false when the box is missed, behind, beyond tMax, or the origin is inside it.
bool hitAabb(const StreetBox& b, const Ray& r, float tMax, float& t, int& axis) {
    float tNear = 0.f, tFar = tMax;
    int entry = -1;
    for (int a = 0; a < 3; ++a) {
        float t0 = (comp(b.lo, a) - comp(r.o, a)) * comp(r.invD, a);
        float t1 = (comp(b.hi, a) - comp(r.o, a)) * comp(r.invD, a);
        if (t0 > t1) std::swap(t0, t1);
        if (t0 > tNear) tNear = t0, entry = a;
        tFar = std::min(tFar, t1);
        if (tNear > tFar) return false;
    }
    if (entry < 0) return false;  // origin inside (no scene ray starts inside a box)
    t = tNear;
    axis = entry;
    return true;
}

bool inside(const StreetBox& b, V3 p) {
    return p.x > b.lo.x && p.x < b.hi.x && p.y > b.lo.y && p.y < b.hi.y && p.z > b.lo.z &&
           p.z < b.hi.z;
}

Camera streetCamera(const SceneOptions& opt, int frame) {
    const float t = opt.staticCamera ? 0.f : float(frame - 1);
    if (opt.cameraCutFrame >= 0 && frame >= opt.cameraCutFrame) {
        // Second viewpoint: high on the right pavement, looking back across the street.
        const V3 pos{3.4f - 0.03f * t, 2.6f, -2.0f};
        return lookAtCamera(pos, {-3.0f, 0.8f, -11.f}, opt.width, opt.height);
    }
    // Dolly forward about 1.2 m while panning about 6 degrees left over 12 frames.
    const float s = std::sin(0.09f * t);
    const V3 pos{0.3f, 1.6f, 3.0f - 1.3f * s};
    const float yaw = 0.12f * s;
    return lookAtCamera(pos, pos + V3{-std::sin(yaw), -0.02f, -std::cos(yaw)}, opt.width,
                        opt.height);
}

void addStaticBoxes(StreetState& s) {
    s.boxes.push_back({{-40.f, -1.f, -160.f}, {40.f, 0.f, 20.f}, kGround});
    s.boxes.push_back({{-13.f, 0.f, -34.f}, {-4.5f, 5.5f, -3.f}, kLeftBuilding});
    s.boxes.push_back({{4.5f, 0.f, -45.f}, {12.f, 7.f, -6.f}, kRightBuilding});
    s.boxes.push_back({{4.3f, 2.6f, -10.4f}, {4.5f, 3.3f, -9.3f}, kSign});
    // About 0.15 m: 1-2 px at 96x64 from where the camera stands.
    s.boxes.push_back({{2.55f, 0.f, -8.07f}, {2.7f, 3.62f, -7.93f}, kLampPost});
}

void addFence(StreetState& s) {
    // Pickets 0.1 m wide every 0.45 m along the left pavement, and a rail: about 1 px wide.
    constexpr float kX0 = -3.3f, kX1 = -3.2f, kZNear = -2.f, kZFar = -9.3f;
    for (float z = kZNear; z > kZFar; z -= 0.45f)
        s.fence.push_back({{kX0, 0.f, z - 0.1f}, {kX1, 1.1f, z}, kFence});
    s.fence.push_back({{kX0, 0.84f, kZFar}, {kX1 + 0.02f, 0.92f, kZNear}, kFence});
    s.fenceBounds = {{kX0, 0.f, kZFar - 0.1f}, {kX1 + 0.02f, 1.1f, kZNear}, kFence};
}

void setLights(StreetState& s, bool night) {
    if (night) {
        s.skyHorizon = {0.03f, 0.035f, 0.06f};
        s.skyZenith = {0.004f, 0.006f, 0.016f};
        s.sun = false;
        s.signRadiance = {5.f, 1.f, 3.f};
        s.lampRadiance = {95.f, 80.f, 55.f};
    } else {
        s.skyHorizon = {0.85f, 0.92f, 1.05f};
        s.skyZenith = {0.18f, 0.36f, 0.85f};
        s.sun = true;
        s.sunDir = normalize(V3{-0.55f, 0.65f, 0.52f});
        s.sunIrradiance = {4.2f, 3.9f, 3.3f};
        s.signRadiance = {7.f, 1.4f, 4.f};
        s.lampRadiance = {12.f, 11.f, 8.f};
    }
}

// Brick paving: 0.32 x 0.24 m bricks in offset rows with mortar joints, each brick a little
// darker or lighter (a few pixels per brick near the camera, finer than a pixel far away).
V3 brickAlbedo(V3 p) {
    constexpr float kLength = 0.32f, kRow = 0.24f, kJoint = 0.025f;
    const float row = std::floor(p.z / kRow);
    const float shift = (int(row) & 1) ? 0.5f * kLength : 0.f;
    const float col = std::floor((p.x + shift) / kLength);
    const float u = p.x + shift - col * kLength, v = p.z - row * kRow;
    if (u < kJoint || v < kJoint) return {0.62f, 0.6f, 0.55f};
    const uint32_t h = hash32(uint32_t(int(col) * 7919) ^ hash32(uint32_t(int(row))));
    const float shade = 0.7f + 0.4f * float(h >> 8) * 0x1p-24f;
    return V3{0.52f, 0.26f, 0.17f} * shade;
}

// Facades: a grid of glossy dark windows (1.5 m bays, 1.8 m storeys) on the street-facing wall.
Material facade(V3 p, bool left, bool streetFace) {
    Material m;
    m.kd = left ? V3{0.72f, 0.62f, 0.5f} : V3{0.58f, 0.62f, 0.7f};
    if (!streetFace || p.y < 0.9f) return m;
    const float u = fract(p.z / 1.5f), v = fract(p.y / 1.8f);
    if (u > 0.2f && u < 0.8f && v > 0.3f && v < 0.85f) {
        m.kd = {0.04f, 0.05f, 0.07f};
        m.ks = {0.5f, 0.5f, 0.5f};
        m.exponent = 400.f;
    }
    return m;
}

// Red van body with a clear coat, dark glossy windows on its upper half.
Material vanMaterial(V3 local) {
    Material m;
    m.kd = {0.55f, 0.04f, 0.03f};
    m.ks = {0.05f, 0.05f, 0.05f};
    m.exponent = 150.f;
    if (local.y > 0.25f && std::fabs(local.x) < 1.0f) {
        m.kd = {0.03f, 0.03f, 0.04f};
        m.ks = {0.3f, 0.3f, 0.3f};
        m.exponent = 300.f;
    }
    return m;
}

}  // namespace

StreetState makeStreet(const SceneOptions& opt, int frame) {
    StreetState s;
    s.camera = streetCamera(opt, frame);
    setLights(s, opt.kind == Kind::StreetNight);
    if (opt.lightChangeFrame >= 0 && frame >= opt.lightChangeFrame) {
        s.sunIrradiance = s.sunIrradiance * opt.lightChangeScale;
        s.lampRadiance = s.lampRadiance * opt.lightChangeScale;
    }
    addStaticBoxes(s);
    addFence(s);

    // The van crosses the street from kerb to kerb (ease in and out) behind the lamp post and
    // the gold sphere, about 13 m from the camera.
    const float t = opt.movingObject ? float(frame - 1) : 0.f;
    const float vx = -3.2f + 6.4f * (0.5f - 0.5f * std::cos(0.28f * t));
    s.vanPos = {vx, 0.95f, -10.5f};
    s.boxes.push_back({s.vanPos - V3{1.2f, 0.8f, 0.7f}, s.vanPos + V3{1.2f, 0.8f, 0.7f}, kVan});

    s.spheres.push_back({{1.6f, 0.65f, -6.5f}, 0.65f, kGoldSphere});
    s.spheres.push_back({{-1.5f, 0.45f, -4.6f}, 0.45f, kChromeSphere});
    s.lampCenter = {2.62f, 3.8f, -8.f};
    s.lampRadius = 0.2f;
    s.spheres.push_back({s.lampCenter, s.lampRadius, kLampHead});

    for (auto& m : s.objectToWorld) m = Mat4::identity();
    // Objects other than the walls and the ground are placed by a translation (no rotation).
    auto place = [&](int id, V3 t) { s.objectToWorld[id] = rigidY(0.f, t); };
    place(kGoldSphere, s.spheres[0].center);
    place(kChromeSphere, s.spheres[1].center);
    place(kLampHead, s.lampCenter);
    place(kVan, s.vanPos);
    for (int i = 0; i < kStreetObjectCount; ++i)
        s.worldToObject[i] = rigidInverse(s.objectToWorld[i]);
    return s;
}

bool intersectStreet(const StreetState& s, const Ray& r, float tMax, Hit& hit) {
    float best = tMax, t;
    int axis = -1, bestAxis = -1;
    const StreetBox* box = nullptr;
    const SphereObj* sphere = nullptr;
    for (const StreetBox& b : s.boxes)
        if (hitAabb(b, r, best, t, axis)) best = t, box = &b, bestAxis = axis;
    // The pickets are only tested by rays that reach the fence's bounds (most do not).
    if (inside(s.fenceBounds, r.o) || hitAabb(s.fenceBounds, r, best, t, axis)) {
        for (const StreetBox& b : s.fence)
            if (hitAabb(b, r, best, t, axis)) best = t, box = &b, bestAxis = axis;
    }
    for (const SphereObj& sp : s.spheres)
        if (hitSphere(sp, r, best, t)) best = t, sphere = &sp, box = nullptr;
    if (!box && !sphere) return false;
    hit.t = best;
    const V3 p = r.o + r.d * best;
    if (sphere) {
        hit.id = sphere->id;
        hit.local = p - sphere->center;
        hit.normal = normalize(hit.local);
    } else {
        hit.id = box->id;
        // Outward normal of the entry face: against the ray on that axis.
        V3 n{0, 0, 0};
        const float sign = comp(r.d, bestAxis) > 0.f ? -1.f : 1.f;
        (bestAxis == 0 ? n.x : bestAxis == 1 ? n.y : n.z) = sign;
        hit.normal = n;
        hit.local = xformPoint(s.worldToObject[hit.id], p);
    }
    return true;
}

bool occludedStreet(const StreetState& s, const Ray& r, float tMax) {
    // Any hit ends the search (shadow rays are half of all rays).
    float t;
    int axis;
    for (const StreetBox& b : s.boxes)
        if (hitAabb(b, r, tMax, t, axis)) return true;
    if (inside(s.fenceBounds, r.o) || hitAabb(s.fenceBounds, r, tMax, t, axis))
        for (const StreetBox& b : s.fence)
            if (hitAabb(b, r, tMax, t, axis)) return true;
    for (const SphereObj& sp : s.spheres)
        if (hitSphere(sp, r, tMax, t)) return true;
    return false;
}

Material materialAt(const StreetState& s, const Hit& hit, V3 p) {
    Material m;
    switch (hit.id) {
        case kGround:
            m.kd = brickAlbedo(p);
            return m;
        case kLeftBuilding:
            return facade(p, true, hit.normal.x > 0.5f);
        case kRightBuilding:
            return facade(p, false, hit.normal.x < -0.5f);
        case kGoldSphere:  // metal: no diffuse lobe, a gold-tinted glossy one
            m.ks = {1.0f, 0.76f, 0.33f};
            m.exponent = 60.f;
            return m;
        case kChromeSphere:  // near-mirror
            m.ks = {0.92f, 0.92f, 0.95f};
            m.exponent = 3000.f;
            return m;
        case kSign:
            m.emission = s.signRadiance;
            return m;
        case kLampHead:
            m.emission = s.lampRadiance;
            return m;
        case kLampPost:
            m.kd = {0.18f, 0.2f, 0.22f};
            return m;
        case kFence:
            m.kd = {0.85f, 0.85f, 0.8f};
            return m;
        case kVan:
            return vanMaterial(hit.local);
        default:
            return m;
    }
}

V3 skyRadiance(const StreetState& s, V3 d) {
    // Square root: the blue deepens quickly above the horizon, like a clear sky.
    const float up = std::sqrt(std::clamp(d.y, 0.f, 1.f));
    return lerp(s.skyHorizon, s.skyZenith, up);
}

}  // namespace kestrel::scenegen
