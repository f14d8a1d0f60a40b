#include "Scene.h"

#include <algorithm>

namespace kestrel::scenegen {

namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kFovY = 50.f * kPi / 180.f;

// Room bounds (metres, +Y up); the front (+Z) is open so the camera can stand outside it.
constexpr float kX0 = -2.f, kX1 = 2.f, kY0 = 0.f, kY1 = 2.6f, kZ0 = -4.5f, kZ1 = 1.f;

Camera makeCamera(V3 pos, V3 target, int width, int height) {
    Camera c;
    c.pos = pos;
    c.width = width;
    c.height = height;
    const V3 f = normalize(target - pos);
    const V3 r = normalize(cross(f, V3{0, 1, 0}));
    const V3 u = cross(r, f);
    c.cameraToWorld = {r.x, u.x, -f.x, pos.x, r.y, u.y, -f.y, pos.y,
                       r.z, u.z, -f.z, pos.z, 0,   0,   0,    1};
    c.worldToCamera = rigidInverse(c.cameraToWorld);
    c.tanY = std::tan(0.5f * kFovY);
    c.tanX = c.tanY * float(width) / float(std::max(height, 1));
    const float n = c.nearPlane, fa = c.farPlane;
    // OpenGL perspective (glFrustum with symmetric bounds).
    c.projection = {1.f / c.tanX,
                    0,
                    0,
                    0,
                    0,
                    1.f / c.tanY,
                    0,
                    0,
                    0,
                    0,
                    -(fa + n) / (fa - n),
                    -2.f * fa * n / (fa - n),
                    0,
                    0,
                    -1,
                    0};
    const float w = float(width), h = float(height);
    // ndc -> pixels: px = (ndc.x + 1) / 2 * W, py = (1 - ndc.y) / 2 * H (y down).
    const Mat4 viewport = {w / 2, 0, 0, w / 2, 0, -h / 2, 0, h / 2, 0, 0, 1, 0, 0, 0, 0, 1};
    c.worldToPixel = viewport * (c.projection * c.worldToCamera);
    return c;
}

AxisQuad quad(int axis, float c, float u0, float u1, float v0, float v1, V3 n, int id) {
    const int ua = (axis + 1) % 3, va = (axis + 2) % 3;
    return {axis, ua, va, c, u0, u1, v0, v1, n, id};
}

bool hitQuad(const AxisQuad& q, const Ray& r, float tMax, float& t) {
    const float tt = (q.c - comp(r.o, q.axis)) * comp(r.invD, q.axis);
    if (!(tt > 0.f && tt < tMax)) return false;
    const float u = comp(r.o, q.ua) + tt * comp(r.d, q.ua);
    const float v = comp(r.o, q.va) + tt * comp(r.d, q.va);
    if (u < q.u0 || u > q.u1 || v < q.v0 || v > q.v1) return false;
    t = tt;
    return true;
}

// Slab test of an axis-aligned box [lo, hi] (world or local space): entry/exit distances.
inline bool slab(float o, float invD, float lo, float hi, float& tNear, float& tFar) {
    float t0 = (lo - o) * invD, t1 = (hi - o) * invD;
    if (t0 > t1) std::swap(t0, t1);
    tNear = std::max(tNear, t0);
    tFar = std::min(tFar, t1);
    return tNear <= tFar;
}

// Cheap rejection against the box's world-space bounds (most rays miss every box).
inline bool hitBounds(const BoxObj& b, const Ray& r, float tMax) {
    float tNear = 0.f, tFar = tMax;
    return slab(r.o.x, r.invD.x, b.lo.x, b.hi.x, tNear, tFar) &&
           slab(r.o.y, r.invD.y, b.lo.y, b.hi.y, tNear, tFar) &&
           slab(r.o.z, r.invD.z, b.lo.z, b.hi.z, tNear, tFar);
}

// Slab test in the box's local frame; returns the entry distance and the local normal.
bool hitBox(const BoxObj& b, const Ray& r, float tMax, float& t, V3* localN, V3* localP) {
    if (!hitBounds(b, r, tMax)) return false;
    const V3 o = xformPoint(b.toLocal, r.o), d = xformDir(b.toLocal, r.d);
    const Ray lr = makeRay(o, d);
    float tNear = 0.f, tFar = tMax;
    if (!slab(o.x, lr.invD.x, -b.half.x, b.half.x, tNear, tFar) ||
        !slab(o.y, lr.invD.y, -b.half.y, b.half.y, tNear, tFar) ||
        !slab(o.z, lr.invD.z, -b.half.z, b.half.z, tNear, tFar) || tNear <= 0.f)
        return false;  // a ray starting inside a box never happens in this scene
    t = tNear;
    const V3 p = o + d * tNear;
    if (localP) *localP = p;
    if (localN) {
        // The face hit is the one whose plane the point lies on (largest relative coordinate).
        const float ax = std::fabs(p.x) / b.half.x, ay = std::fabs(p.y) / b.half.y,
                    az = std::fabs(p.z) / b.half.z;
        if (ax >= ay && ax >= az)
            *localN = {std::copysign(1.f, p.x), 0, 0};
        else if (ay >= az)
            *localN = {0, std::copysign(1.f, p.y), 0};
        else
            *localN = {0, 0, std::copysign(1.f, p.z)};
    }
    return true;
}

}  // namespace

bool hitSphere(const SphereObj& sp, const Ray& r, float tMax, float& t) {
    const V3 oc = r.o - sp.center;
    const float b = dot(oc, r.d);
    const float c = dot(oc, oc) - sp.radius * sp.radius;
    const float disc = b * b - c;
    if (disc < 0.f) return false;
    const float sq = std::sqrt(disc);
    float tt = -b - sq;
    if (tt <= 0.f) tt = -b + sq;
    if (tt <= 0.f || tt >= tMax) return false;
    t = tt;
    return true;
}

Camera lookAtCamera(V3 pos, V3 target, int width, int height) {
    return makeCamera(pos, target, width, height);
}

SceneState makeScene(const SceneOptions& opt, int frame) {
    SceneState s{};
    // Animation parameter: frame 1 is s = 0; formulas are smooth and bounded for any frame.
    const float camT = opt.staticCamera ? 0.f : float(frame - 1);
    const float objT = opt.movingObject ? float(frame - 1) : 0.f;

    const bool cut = opt.cameraCutFrame >= 0 && frame >= opt.cameraCutFrame;
    if (!cut) {
        // Outside the open front, dollying in and panning slightly.
        const V3 pos{0.35f * std::sin(0.21f * camT), 1.25f + 0.05f * std::sin(0.13f * camT),
                     3.6f + 0.4f * std::cos(0.14f * camT)};
        const V3 target{0.15f * std::sin(0.17f * camT), 1.0f, -2.5f};
        s.camera = makeCamera(pos, target, opt.width, opt.height);
    } else {
        // Second viewpoint: inside the room, high on the right, looking at the far left corner.
        const V3 pos{1.5f - 0.04f * camT, 1.9f, 0.6f};
        const V3 target{-1.0f, 0.6f, -3.3f};
        s.camera = makeCamera(pos, target, opt.width, opt.height);
    }

    for (auto& m : s.objectToWorld) m = Mat4::identity();
    s.objectToWorld[kTallBox] = rigidY(0.35f, {-1.1f, 0.9f, -3.3f});
    s.objectToWorld[kShortBox] = rigidY(-0.3f, {1.0f, 0.35f, -2.4f});
    s.objectToWorld[kBigSphere] = rigidY(0.f, {0.1f, 0.5f, -3.7f});
    s.objectToWorld[kMovingSphere] =
        rigidY(0.f, {-0.2f + 0.9f * std::sin(0.25f * objT), 0.3f, -1.2f});
    s.objectToWorld[kGlowSphere] = rigidY(0.f, {1.0f, 0.83f, -2.4f});
    // The ceiling light swinging along x (lightSwing; 0: still): its pool and the shadows move
    // where the geometry does not. Its object transform moves with it, so the motion vectors of
    // the light itself are right.
    const float swing = opt.lightSwing * std::sin(0.35f * float(frame - 1));
    s.objectToWorld[kAreaLight] = rigidY(0.f, {swing, 0.f, 0.f});
    for (int i = 0; i < kObjectCount; ++i) s.worldToObject[i] = rigidInverse(s.objectToWorld[i]);

    // Walls: normals point into the room.
    s.quads[0] = quad(1, kY0, kZ0, kZ1, kX0, kX1, {0, 1, 0}, kFloor);  // y: u = z, v = x
    s.quads[1] = quad(1, kY1, kZ0, kZ1, kX0, kX1, {0, -1, 0}, kCeiling);
    s.quads[2] = quad(2, kZ0, kX0, kX1, kY0, kY1, {0, 0, 1}, kBackWall);  // z: u = x, v = y
    s.quads[3] = quad(0, kX0, kY0, kY1, kZ0, kZ1, {1, 0, 0}, kLeftWall);  // x: u = y, v = z
    s.quads[4] = quad(0, kX1, kY0, kY1, kZ0, kZ1, {-1, 0, 0}, kRightWall);
    s.lightY = kY1 - 0.01f;
    s.lightX0 = -0.7f + swing, s.lightX1 = 0.7f + swing, s.lightZ0 = -3.1f, s.lightZ1 = -1.7f;
    s.lightArea = (s.lightX1 - s.lightX0) * (s.lightZ1 - s.lightZ0);
    s.lightRadiance = {16.f, 14.5f, 12.5f};
    s.quads[5] =
        quad(1, s.lightY, s.lightZ0, s.lightZ1, s.lightX0, s.lightX1, {0, -1, 0}, kAreaLight);

    auto translation = [&](int id) {
        const Mat4& m = s.objectToWorld[id];
        return V3{m.m[0][3], m.m[1][3], m.m[2][3]};
    };
    s.spheres[0] = {translation(kBigSphere), 0.5f, kBigSphere};
    s.spheres[1] = {translation(kMovingSphere), 0.3f, kMovingSphere};
    s.spheres[2] = {translation(kGlowSphere), 0.13f, kGlowSphere};
    s.glowCenter = s.spheres[2].center;
    s.glowRadius = s.spheres[2].radius;
    s.glowRadiance = {8.f, 4.f, 1.2f};
    s.boxes[0] = {
        s.objectToWorld[kTallBox], s.worldToObject[kTallBox], {0.4f, 0.9f, 0.4f}, kTallBox, {}, {}};
    s.boxes[1] = {s.objectToWorld[kShortBox],
                  s.worldToObject[kShortBox],
                  {0.45f, 0.35f, 0.45f},
                  kShortBox,
                  {},
                  {}};
    for (BoxObj& b : s.boxes) {
        b.lo = {1e30f, 1e30f, 1e30f};
        b.hi = {-1e30f, -1e30f, -1e30f};
        for (int c = 0; c < 8; ++c) {
            const V3 corner{c & 1 ? b.half.x : -b.half.x, c & 2 ? b.half.y : -b.half.y,
                            c & 4 ? b.half.z : -b.half.z};
            const V3 w = xformPoint(b.toWorld, corner);
            b.lo = {std::min(b.lo.x, w.x), std::min(b.lo.y, w.y), std::min(b.lo.z, w.z)};
            b.hi = {std::max(b.hi.x, w.x), std::max(b.hi.y, w.y), std::max(b.hi.z, w.z)};
        }
        // Pad so that rounding never rejects a grazing hit of the exact box.
        b.lo = b.lo - V3{1e-4f, 1e-4f, 1e-4f};
        b.hi = b.hi + V3{1e-4f, 1e-4f, 1e-4f};
    }
    return s;
}

bool intersect(const SceneState& s, const Ray& r, float tMax, Hit& hit, bool insideRoom) {
    float best = tMax, t;
    int kind = -1, index = -1;  // 0 quad, 1 sphere, 2 box
    if (insideRoom) {
        // Exit of the room box: on each axis the wall the ray heads to; the nearest wins.
        const float tx = ((r.d.x > 0.f ? kX1 : kX0) - r.o.x) * r.invD.x;
        const float ty = ((r.d.y > 0.f ? kY1 : kY0) - r.o.y) * r.invD.y;
        const float tz = ((r.d.z > 0.f ? kZ1 : kZ0) - r.o.z) * r.invD.z;
        int wall;
        float tw;
        if (tx <= ty && tx <= tz)
            tw = tx, wall = r.d.x > 0.f ? 4 : 3;
        else if (ty <= tz)
            tw = ty, wall = r.d.y > 0.f ? 1 : 0;
        else
            tw = tz, wall = r.d.z > 0.f ? -1 : 2;  // +Z: out through the open front
        if (wall >= 0 && tw > 0.f && tw < best) best = tw, kind = 0, index = wall;
        if (hitQuad(s.quads[5], r, best, t)) best = t, kind = 0, index = 5;
    } else {
        for (int i = 0; i < 6; ++i)
            if (hitQuad(s.quads[i], r, best, t)) best = t, kind = 0, index = i;
    }
    for (int i = 0; i < 3; ++i)
        if (hitSphere(s.spheres[i], r, best, t)) best = t, kind = 1, index = i;
    for (int i = 0; i < 2; ++i)
        if (hitBox(s.boxes[i], r, best, t, nullptr, nullptr)) best = t, kind = 2, index = i;
    if (kind < 0) return false;
    hit.t = best;
    const V3 p = r.o + r.d * best;
    if (kind == 0) {
        const AxisQuad& q = s.quads[index];
        hit.id = q.id;
        hit.normal = q.normal;
        hit.local = p;  // walls are placed in world space (identity transform)
    } else if (kind == 1) {
        const SphereObj& sp = s.spheres[index];
        hit.id = sp.id;
        hit.local = p - sp.center;
        hit.normal = normalize(hit.local);
    } else {
        const BoxObj& b = s.boxes[index];
        V3 ln, lp;
        hitBox(b, r, tMax, t, &ln, &lp);
        hit.id = b.id;
        hit.normal = xformDir(b.toWorld, ln);
        hit.local = lp;
    }
    return true;
}

bool occluded(const SceneState& s, const Ray& r, float tMax) {
    float t;
    for (int i = 0; i < 3; ++i)
        if (hitSphere(s.spheres[i], r, tMax, t)) return true;
    for (int i = 0; i < 2; ++i)
        if (hitBox(s.boxes[i], r, tMax, t, nullptr, nullptr)) return true;
    return false;
}

V3 albedoAt(const Hit& hit, V3 p) {
    switch (hit.id) {
        case kFloor: {
            // 0.5 m checker: strong texture so that albedo demodulation matters.
            const int cx = int(std::floor(p.x * 2.f)), cz = int(std::floor(p.z * 2.f));
            return ((cx + cz) & 1) ? V3{0.78f, 0.74f, 0.68f} : V3{0.16f, 0.19f, 0.26f};
        }
        case kCeiling:
            return {0.8f, 0.8f, 0.8f};
        case kBackWall:
            return {0.72f, 0.72f, 0.7f};
        case kLeftWall:
            return {0.7f, 0.16f, 0.12f};
        case kRightWall:
            return {0.14f, 0.55f, 0.2f};
        case kTallBox: {  // horizontal stripes in object space
            const int band = int(std::floor((hit.local.y + 0.9f) * 5.f));
            return (band & 1) ? V3{0.2f, 0.33f, 0.75f} : V3{0.85f, 0.84f, 0.8f};
        }
        case kShortBox:
            return {0.8f, 0.68f, 0.42f};
        case kBigSphere:
            return {0.7f, 0.7f, 0.72f};
        case kMovingSphere: {  // stripes that travel with the sphere
            const int band = int(std::floor((hit.local.x + 0.3f) * 10.f));
            return (band & 1) ? V3{0.9f, 0.35f, 0.1f} : V3{0.95f, 0.9f, 0.75f};
        }
        default:
            return {0, 0, 0};  // emitters do not reflect
    }
}

V3 emissionAt(const SceneState& s, const Hit& hit, V3 d) {
    if (hit.id == kGlowSphere) return s.glowRadiance;
    if (hit.id == kAreaLight && d.y > 0.f) return s.lightRadiance;  // seen from below
    return {0, 0, 0};
}

}  // namespace kestrel::scenegen
