#pragma once
// A synthetic frame pair for the Reprojection equivalence test and benchmark: a sloped
// background plane and discs (objects) moving against a panning camera, so motion vectors vary
// smoothly with fractional parts (the integer tap offset changes every ~60 pixels along a row,
// ~90% of 8-pixel groups share one, as in the shipped 1080p bench scene), object edges
// disocclude, ids and depths differ per object,
// and last frame's G-buffer is the same scene at the previous positions.
#include <kestrel/Image.h>

#include <cmath>
#include <cstdint>

namespace reprojscene {

using kestrel::Format;
using kestrel::Image;

inline float hash01(int x, int y, int seed) {
    uint32_t h = uint32_t(x) * 73856093u ^ uint32_t(y) * 19349663u ^ uint32_t(seed) * 83492791u;
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    return float(h & 0xffffff) / float(0x1000000);
}

struct Frames {
    Image depth, normal, objectId, motion, position;
    Image prevDepth, prevNormal, prevObjectId, prevColor, prevMoments, prevHistoryLength;
};

struct Disc {
    float cx, cy, r, depth, vx, vy;  ///< centre now, radius, depth, motion to the previous frame
};

/// `seed` varies the layout; `motionScale` scales every velocity (0: static scene).
inline Frames makeFrames(int w, int h, int seed, float motionScale = 1.f) {
    Frames f{Image(w, h, Format::Float),  Image(w, h, Format::Float3), Image(w, h, Format::Int32),
             Image(w, h, Format::Float2), Image(w, h, Format::Float3), Image(w, h, Format::Float),
             Image(w, h, Format::Float3), Image(w, h, Format::Int32),  Image(w, h, Format::Float3),
             Image(w, h, Format::Float2), Image(w, h, Format::Float)};
    constexpr int kDiscs = 7;
    Disc discs[kDiscs];
    for (int k = 0; k < kDiscs; ++k) {
        const float s = float(std::min(w, h));
        discs[k] = {float(w) * hash01(k, 1, seed),
                    float(h) * hash01(k, 2, seed),
                    s * (0.05f + 0.2f * hash01(k, 3, seed)),
                    2.f + 3.f * float(k) / kDiscs,
                    motionScale * (8.f * hash01(k, 4, seed) - 4.f),
                    motionScale * (6.f * hash01(k, 5, seed) - 3.f)};
    }
    // Camera pan: previous position = current + (panX + slope * x, panY).
    const float panX = motionScale * (1.3f + hash01(9, 9, seed)), panY = motionScale * 0.37f;
    const float slope = motionScale * 0.0007f;
    // What the frame at time `prev` shows at continuous pixel (px, py).
    struct Hit {
        int id;
        float depth, nx, ny, nz;
    };
    auto shade = [&](float px, float py, bool prev) -> Hit {
        Hit best{0, 10.f + 0.004f * py, 0.f, 0.3f, 0.954f};  // background plane
        for (int k = 0; k < kDiscs; ++k) {
            const Disc& d = discs[k];
            const float cx = prev ? d.cx + d.vx : d.cx, cy = prev ? d.cy + d.vy : d.cy;
            const float dx = (px - cx) / d.r, dy = (py - cy) / d.r, q = dx * dx + dy * dy;
            if (q >= 1.f) continue;
            const float z = d.depth - 0.5f * std::sqrt(1.f - q);
            if (z < best.depth) best = {k + 1, z, dx, -dy, std::sqrt(1.f - q)};
        }
        return best;
    };
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float px = float(x) + 0.5f, py = float(y) + 0.5f;
            const Hit cur = shade(px, py, false);
            // A smooth ripple (perspective, deformation): the integer tap offset changes
            // every ~60 pixels along a row, as in the shipped bench scene's motion vectors.
            float mx = panX + slope * px + motionScale * 0.6f * std::sin(0.02f * px + 0.03f * py),
                  my = panY + motionScale * 0.4f * std::cos(0.012f * px - 0.02f * py);
            if (cur.id > 0) {
                mx += discs[cur.id - 1].vx;
                my += discs[cur.id - 1].vy;
            }
            f.depth.at(0, x, y) = cur.depth;
            f.normal.at(0, x, y) = cur.nx;
            f.normal.at(1, x, y) = cur.ny;
            f.normal.at(2, x, y) = cur.nz;
            f.objectId.atInt(x, y) = cur.id;
            f.motion.at(0, x, y) = mx;
            f.motion.at(1, x, y) = my;
            f.position.at(0, x, y) = px;
            f.position.at(1, x, y) = py;
            f.position.at(2, x, y) = -cur.depth;
            // Last frame: the camera was panned, so pixel (x, y) then saw the scene at
            // (x - pan, y - pan) of the current camera.
            const float qx = px - panX - slope * px, qy = py - panY;
            const Hit prev = shade(qx, qy, true);
            f.prevDepth.at(0, x, y) = prev.depth;
            f.prevNormal.at(0, x, y) = prev.nx;
            f.prevNormal.at(1, x, y) = prev.ny;
            f.prevNormal.at(2, x, y) = prev.nz;
            f.prevObjectId.atInt(x, y) = prev.id;
            const float base = 0.2f + 0.6f * hash01(prev.id, 7, seed);
            for (int c = 0; c < 3; ++c)
                f.prevColor.at(c, x, y) =
                    base * (1.f + 0.3f * float(c)) + 0.5f * hash01(x, y, seed * 3 + c);
            const float l = f.prevColor.at(1, x, y);
            f.prevMoments.at(0, x, y) = l;
            f.prevMoments.at(1, x, y) = l * l + 0.1f * hash01(x, y, seed + 11);
            f.prevHistoryLength.at(0, x, y) = std::floor(1.f + 31.f * hash01(x, y, seed + 17));
        }
    return f;
}

}  // namespace reprojscene
