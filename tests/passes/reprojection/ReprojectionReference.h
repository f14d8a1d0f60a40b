#pragma once
// Plain scalar reference of the Reprojection pass: the straightforward per-pixel form of the
// formula (every tap read through ImageView::at() and sanitised where it is used, derivatives
// recomputed per pixel, transforms looked up in a std::map), kept to check the optimised pass
// against. Same formula, same parameters, same evaluation order of every floating-point
// expression and the same roundings (both built with -ffp-contract=off, each fused
// multiply-add written as std::fma), so the two agree bit for bit at any optimisation level.
#include <kestrel/FrameContext.h>
#include <kestrel/Image.h>
#include <kestrel/PixelMath.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include "DepthChangeModel.h"

namespace reprojref {

using namespace kestrel;

/// Bound and valid inputs; null = unbound (or an invalid history).
struct Inputs {
    const Image* depth = nullptr;
    const Image* normal = nullptr;
    const Image* objectId = nullptr;
    const Image* motion = nullptr;
    const Image* position = nullptr;
    const Image* prevDepth = nullptr;
    const Image* prevNormal = nullptr;
    const Image* prevObjectId = nullptr;
    const Image* prevColor = nullptr;
    const Image* prevMoments = nullptr;
    const Image* prevHistoryLength = nullptr;
    const SceneData* scene = nullptr;
    const SceneData* previousScene = nullptr;
};

struct Params {
    bool catmullRom = false;
    float depthThreshold = 10.f, normalThreshold = 16.f;
    float depthPrecision = 0.f;  ///< relative step r of the stored depth (0: float)
};

struct Outputs {
    Image color, moments, historyLength;
    Image taps;  ///< Int32: which taps passed (the pass's `taps` layout, below)
};

// The `taps` bits: tap (x0 + k, y0 + j) of the 4x4 footprint at (j + 1) 4 + k + 1, tap
// (cx + k, cy + j) of the 3x3 fallback at 16 + (j + 1) 3 + k + 1.
inline int tapBit(int k, int j) {
    return (j + 1) * 4 + k + 1;
}
inline int fallbackBit(int k, int j) {
    return 16 + (j + 1) * 3 + k + 1;
}

inline void catmullRomWeights(float t, float w[4]) {
    const float t2 = t * t, t3 = t2 * t;
    w[0] = -0.5f * t3 + t2 - 0.5f * t;
    w[1] = 1.5f * t3 - 2.5f * t2 + 1.f;
    w[2] = -1.5f * t3 + 2.f * t2 + 0.5f * t;
    w[3] = 0.5f * t3 - 0.5f * t2;
}

inline Outputs reproject(const Inputs& in, const Params& p) {
    const int w = in.depth->width(), h = in.depth->height();
    Outputs out{Image(w, h, Format::Float3), Image(w, h, Format::Float2),
                Image(w, h, Format::Float), Image(w, h, Format::Int32)};  // zero-initialised
    if (!in.prevDepth || !in.prevNormal || (!in.prevColor && !in.prevMoments)) return out;
    const Image &depth = *in.depth, &normal = *in.normal, &pDepth = *in.prevDepth,
                &pNormal = *in.prevNormal;
    const Image* pColor = in.prevColor;
    const Image* pMoments = in.prevMoments;
    const Image* pHist = in.prevHistoryLength;
    const bool useIds = in.objectId && in.prevObjectId;
    const bool matrices = !in.motion && in.position && in.scene && in.previousScene &&
                          in.scene->hasCamera && in.previousScene->hasCamera;
    // Per-object transforms (current world -> previous pixel / previous camera).
    struct T {
        Mat4 toPrevPixel, toPrevCamera;
    };
    std::map<int32_t, T> byId;
    T fallback{};
    if (matrices) {
        fallback = {in.previousScene->worldToPixel, in.previousScene->worldToCamera};
        for (const auto& [id, o2w] : in.scene->objectToWorld) {
            auto it = in.previousScene->objectToWorld.find(id);
            auto inv = inverse(o2w);
            if (it == in.previousScene->objectToWorld.end() || !inv) continue;
            Mat4 motion = it->second * *inv;
            byId[id] = {in.previousScene->worldToPixel * motion,
                        in.previousScene->worldToCamera * motion};
        }
    }
    const float dThr = p.depthThreshold, nThr = p.normalThreshold;
    // Motion vectors only: last frame's depth of a static surface from the fitted camera model.
    DepthChangeModel depthChange;
    if (in.motion && std::isfinite(dThr))
        depthChange = fitDepthChange(
            {w, h, depth.channel(0), in.motion->channel(0), in.motion->channel(1),
             useIds ? in.objectId->view().ints() : nullptr, pDepth.channel(0),
             useIds ? in.prevObjectId->view().ints() : nullptr, dThr, p.depthPrecision});

    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            float ppx = float(x) + 0.5f, ppy = float(y) + 0.5f;
            float zRef = px::sanitizeDepth(depth.at(0, x, y));
            bool ok = true;
            if (in.motion) {
                ppx += in.motion->at(0, x, y);
                ppy += in.motion->at(1, x, y);
                if (zRef < kBackgroundDepth)
                    zRef = depthChange.predict(zRef, x, depthChange.rowTerm(y));
            } else if (matrices) {
                const int32_t id = in.objectId ? in.objectId->atInt(x, y) : 0;
                if (zRef >= kBackgroundDepth || (in.objectId && id == kBackgroundId)) {
                    ok = false;
                } else {
                    auto it = in.objectId ? byId.find(id) : byId.end();
                    const T& t = it == byId.end() ? fallback : it->second;
                    Vec3 q{in.position->at(0, x, y), in.position->at(1, x, y),
                           in.position->at(2, x, y)};
                    Vec4 s = t.toPrevPixel.transformPoint(q);
                    Vec4 c = t.toPrevCamera.transformPoint(q);
                    ok = s.w > 1e-20f;
                    if (ok) {
                        ppx = s.x / s.w;
                        ppy = s.y / s.w;
                        zRef = -c.z;
                    }
                }
            }
            ok = ok && std::fabs(ppx) < 1e7f && std::fabs(ppy) < 1e7f;

            // Screen-space derivatives (one-sided, edge-preserving).
            const bool l = x > 0, r = x + 1 < w, u = y > 0, d = y + 1 < h;
            auto zAt = [&](int xx, int yy) { return px::sanitizeDepth(depth.at(0, xx, yy)); };
            const float zc = zAt(x, y);
            const bool surface = zc < kBackgroundDepth;  // the background has no slope
            const float fwZ =
                std::fabs(px::minAbsDiff(l ? zAt(x - 1, y) : 0, zc, r ? zAt(x + 1, y) : 0, l, r)) +
                std::fabs(px::minAbsDiff(u ? zAt(x, y - 1) : 0, zc, d ? zAt(x, y + 1) : 0, u, d));
            float n[3], dnx2 = 0, dny2 = 0;
            for (int c = 0; c < 3; ++c) {
                auto nAt = [&](int xx, int yy) { return px::sanitizeNormal(normal.at(c, xx, yy)); };
                n[c] = nAt(x, y);
                const float gx =
                    px::minAbsDiff(l ? nAt(x - 1, y) : 0, n[c], r ? nAt(x + 1, y) : 0, l, r);
                const float gy =
                    px::minAbsDiff(u ? nAt(x, y - 1) : 0, n[c], d ? nAt(x, y + 1) : 0, u, d);
                dnx2 += gx * gx;
                dny2 += gy * gy;
            }
            const float fwN = surface ? std::sqrt(dnx2) + std::sqrt(dny2) : 0.f;
            const float invZ = 1.f / ((surface ? fwZ : 0.f) + 2.f * p.depthPrecision * zc + 1e-2f),
                        invN = 1.f / (fwN + 1e-2f);

            auto passes = [&](int tx, int ty) {
                if (tx < 0 || ty < 0 || tx >= w || ty >= h) return false;
                if (useIds && in.prevObjectId->atInt(tx, ty) != in.objectId->atInt(x, y))
                    return false;
                if (std::fabs(zRef - px::sanitizeDepth(pDepth.at(0, tx, ty))) * invZ > dThr)
                    return false;
                float dn2 = 0;
                for (int c = 0; c < 3; ++c) {
                    const float dn = n[c] - px::sanitizeNormal(pNormal.at(c, tx, ty));
                    dn2 = std::fma(dn, dn, dn2);
                }
                // |n - n_prev| * invN <= nThr, squared (no square root per tap).
                return dn2 * (invN * invN) <= nThr * nThr;
            };
            int32_t& taps = out.taps.atInt(x, y);
            auto consistent = [&](int tx, int ty, int bit) {
                const bool ok = passes(tx, ty);
                taps |= int32_t(ok) << bit;
                return ok;
            };

            float acc[3] = {0, 0, 0}, accM[2] = {0, 0}, accH = 0, sumW = 0;
            auto addTap = [&](int tx, int ty, float wt) {
                if (pColor)
                    for (int c = 0; c < 3; ++c)
                        acc[c] = std::fma(wt, px::sanitize(pColor->at(c, tx, ty)), acc[c]);
                if (pMoments) {
                    accM[0] = std::fma(wt, px::sanitize(pMoments->at(0, tx, ty)), accM[0]);
                    accM[1] =
                        std::fma(wt, px::sanitizePositive(pMoments->at(1, tx, ty), 1e32f), accM[1]);
                }
                accH += wt * (pHist ? px::sanitizePositive(pHist->at(0, tx, ty), 1e6f) : 1.f);
                sumW += wt;
            };
            int x0 = 0, y0 = 0;
            float fx = 0, fy = 0;
            bool all4 = false;
            if (ok) {
                const float bx = ppx - 0.5f, by = ppy - 0.5f;
                x0 = int(std::floor(bx));
                y0 = int(std::floor(by));
                fx = bx - float(x0);
                fy = by - float(y0);
                const float bw[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
                int nOk = 0;
                for (int k = 0; k < 4; ++k) {
                    const int tx = x0 + (k & 1), ty = y0 + (k >> 1);
                    if (!consistent(tx, ty, tapBit(k & 1, k >> 1))) continue;
                    ++nOk;
                    if (bw[k] > 0.f) addTap(tx, ty, bw[k]);
                }
                all4 = nOk == 4;
                if (sumW < 1e-4f) {
                    acc[0] = acc[1] = acc[2] = accM[0] = accM[1] = accH = sumW = 0;
                    const int cx = int(std::floor(ppx)), cy = int(std::floor(ppy));
                    for (int j = -1; j <= 1; ++j)
                        for (int k = -1; k <= 1; ++k)
                            if (consistent(cx + k, cy + j, fallbackBit(k, j)))
                                addTap(cx + k, cy + j, 1.f);
                    all4 = false;
                }
            }
            if (sumW <= 0.f) continue;  // disoccluded: outputs stay 0
            const float inv = 1.f / sumW;
            float col[3] = {acc[0] * inv, acc[1] * inv, acc[2] * inv};
            if (p.catmullRom && pColor && all4 && x0 >= 1 && y0 >= 1 && x0 + 2 < w && y0 + 2 < h) {
                bool all16 = true;
                for (int j = -1; j <= 2 && all16; ++j)
                    for (int k = -1; k <= 2 && all16; ++k)
                        if ((j < 0 || j > 1 || k < 0 || k > 1) &&
                            !consistent(x0 + k, y0 + j, tapBit(k, j)))
                            all16 = false;
                if (all16) {
                    float wx[4], wy[4];
                    catmullRomWeights(fx, wx);
                    catmullRomWeights(fy, wy);
                    for (int c = 0; c < 3; ++c) {
                        float s = 0, lo = 3e38f, hi = -3e38f;
                        for (int j = 0; j < 4; ++j)
                            for (int k = 0; k < 4; ++k) {
                                const float v = px::sanitize(pColor->at(c, x0 - 1 + k, y0 - 1 + j));
                                s = std::fma(wx[k] * wy[j], v, s);
                                if (j >= 1 && j <= 2 && k >= 1 && k <= 2) {
                                    lo = std::min(lo, v);
                                    hi = std::max(hi, v);
                                }
                            }
                        col[c] = px::clamp(s, lo, hi);
                    }
                }
            }
            for (int c = 0; c < 3; ++c) out.color.at(c, x, y) = col[c];
            out.moments.at(0, x, y) = accM[0] * inv;
            out.moments.at(1, x, y) = accM[1] * inv;
            out.historyLength.at(0, x, y) = accH * inv;
        }
    return out;
}

}  // namespace reprojref
