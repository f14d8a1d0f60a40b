#include "ReprojectionPass.h"

#include <kestrel/PixelMath.h>

#include <map>
#include <memory>
#include <vector>

using namespace kestrel;

PassDesc ReprojectionPass::describe() {
    PassDesc d("Reprojection",
               "Reprojects last frame's colour, moments and history length into this frame:"
               " position from motion vectors, else world position + per-object and camera"
               " matrices, else identity; 2x2 bilinear taps with depth/normal/id consistency"
               " tests, 3x3 fallback, else disocclusion (historyLength 0). Optional Catmull-Rom"
               " colour resampling for TAA histories.");
    d.input("depth", Format::Float, "linear view depth")
        .input("normal", Format::Float3, "world-space normal")
        .optionalInput("objectId", Format::Int32, "object id (taps on another object are rejected)")
        .optionalInput("motion", Format::Float2, "screen motion to the previous frame, pixels")
        .optionalInput("position", Format::Float3, "world position (matrix reprojection)")
        .historyInput("prevDepth", Format::Float, "last frame's depth")
        .historyInput("prevNormal", Format::Float3, "last frame's normal")
        .historyInput("prevObjectId", Format::Int32, "last frame's object id")
        .historyInput("prevColor", Format::Float3, "last frame's colour history")
        .historyInput("prevMoments", Format::Float2, "last frame's moments history")
        .historyInput("prevHistoryLength", Format::Float, "last frame's history length")
        .output("color", Format::Float3, "reprojected colour (0 where disoccluded)")
        .output("moments", Format::Float2, "reprojected moments (0 where disoccluded)")
        .output("historyLength", Format::Float,
                "reprojected history length, 0 where disoccluded or without valid history; when"
                " prevHistoryLength is not fed, 1 where the reprojection succeeded")
        .paramEnum("filter", "bilinear", {"bilinear", "catmullrom"},
                   "colour resampling: bilinear (SVGF) or Catmull-Rom 4x4 (sharp, for TAA)")
        .paramFloat("depthThreshold", 10.0, 0.0, 1e6,
                    "max |z - z_prev| / (fwidth(z) + 0.01) of a consistent tap")
        .paramFloat("normalThreshold", 16.0, 0.0, 1e6,
                    "max |n - n_prev| / (fwidth(n) + 0.01) of a consistent tap");
    return d;
}

ReprojectionPass::ReprojectionPass(const ParamValues& p)
    : catmullRom_(p.getString("filter") == "catmullrom"),
      depthThreshold_(p.getFloat("depthThreshold")),
      normalThreshold_(p.getFloat("normalThreshold")) {}

void ReprojectionPass::resolve(ResolveContext& rc) {
    if (!rc.isBound("prevColor")) rc.setAbsent("color", "prevColor is not connected");
    if (!rc.isBound("prevMoments")) rc.setAbsent("moments", "prevMoments is not connected");
    if (rc.isBound("motion"))
        rc.note("reprojecting with motion vectors");
    else if (rc.isBound("position"))
        rc.note("reprojecting with world positions and matrices");
    else
        rc.note("no motion and no position: identity reprojection (static camera assumed)");
}

namespace {

/// Per-object transforms of the matrix path: current world -> previous pixel (and previous
/// camera, for the expected previous depth). GAMES202: Screen_{i-1} = P V M_{i-1} M_i^-1 World_i.
struct ObjectTransforms {
    Mat4 toPrevPixel, toPrevCamera;
};

class TransformTable {
public:
    TransformTable(const SceneData& cur, const SceneData& prev) {
        fallback_ = {prev.worldToPixel, prev.worldToCamera};
        for (const auto& [id, o2w] : cur.objectToWorld) {
            auto it = prev.objectToWorld.find(id);
            auto inv = inverse(o2w);
            if (it == prev.objectToWorld.end() || !inv) continue;
            Mat4 motion = it->second * *inv;
            byId_[id] = {prev.worldToPixel * motion, prev.worldToCamera * motion};
        }
        if (!byId_.empty()) {
            lo_ = byId_.begin()->first;
            int64_t span = int64_t(byId_.rbegin()->first) - lo_ + 1;
            if (span <= 65536) {  // dense table: no map lookup per pixel
                dense_.assign(size_t(span), fallback_);
                for (const auto& [id, t] : byId_) dense_[size_t(id - lo_)] = t;
            }
        }
    }
    const ObjectTransforms& fallback() const { return fallback_; }
    const ObjectTransforms& get(int32_t id) const {
        if (!dense_.empty()) {
            int64_t i = int64_t(id) - lo_;
            return i >= 0 && i < int64_t(dense_.size()) ? dense_[size_t(i)] : fallback_;
        }
        auto it = byId_.find(id);
        return it == byId_.end() ? fallback_ : it->second;
    }

private:
    ObjectTransforms fallback_;  // static objects: camera motion only
    std::map<int32_t, ObjectTransforms> byId_;
    std::vector<ObjectTransforms> dense_;
    int32_t lo_ = 0;
};

// Catmull-Rom weights of the 4 taps around a fraction t in [0,1).
inline void catmullRomWeights(float t, float w[4]) {
    const float t2 = t * t, t3 = t2 * t;
    w[0] = -0.5f * t3 + t2 - 0.5f * t;
    w[1] = 1.5f * t3 - 2.5f * t2 + 1.f;
    w[2] = -1.5f * t3 + 2.f * t2 + 0.5f * t;
    w[3] = 0.5f * t3 - 0.5f * t2;
}

// Screen-space derivatives of one row (one-sided, edge-preserving: px::minAbsDiff), as
// 1 / (fwidth + 0.01) of depth and normal, plus the sanitised normal. Neighbour indices are
// clamped so every load is in range; a clamped neighbour's value is never used (minAbsDiff
// ignores an absent side), so this equals the per-pixel form and vectorises.
void rowDerivatives(const float* __restrict z, const float* __restrict zu,
                    const float* __restrict zd, const float* __restrict a0,
                    const float* __restrict a0u, const float* __restrict a0d,
                    const float* __restrict a1, const float* __restrict a1u,
                    const float* __restrict a1d, const float* __restrict a2,
                    const float* __restrict a2u, const float* __restrict a2d, bool u, bool d, int w,
                    float* __restrict invZ, float* __restrict invN, float* __restrict n0,
                    float* __restrict n1, float* __restrict n2) {
    for (int x = 0; x < w; ++x) {
        const bool l = x > 0, r = x + 1 < w;
        const int xl = l ? x - 1 : x, xr = r ? x + 1 : x;
        const float zc = px::sanitizeDepth(z[x]);
        const float fwZ =
            std::fabs(
                px::minAbsDiff(px::sanitizeDepth(z[xl]), zc, px::sanitizeDepth(z[xr]), l, r)) +
            std::fabs(px::minAbsDiff(px::sanitizeDepth(zu[x]), zc, px::sanitizeDepth(zd[x]), u, d));
        float dnx2 = 0, dny2 = 0;
        auto channel = [&](const float* __restrict p, const float* __restrict pu,
                           const float* __restrict pd) {
            const float c = px::sanitizeNormal(p[x]);
            const float gx =
                px::minAbsDiff(px::sanitizeNormal(p[xl]), c, px::sanitizeNormal(p[xr]), l, r);
            const float gy =
                px::minAbsDiff(px::sanitizeNormal(pu[x]), c, px::sanitizeNormal(pd[x]), u, d);
            dnx2 += gx * gx;
            dny2 += gy * gy;
            return c;
        };
        n0[x] = channel(a0, a0u, a0d);
        n1[x] = channel(a1, a1u, a1d);
        n2[x] = channel(a2, a2u, a2d);
        const float fwN = std::sqrt(dnx2) + std::sqrt(dny2);
        invZ[x] = 1.f / (fwZ + 1e-2f);
        invN[x] = 1.f / (fwN + 1e-2f);
    }
}

}  // namespace

void ReprojectionPass::execute(FrameContext& ctx, PassIO& io) {
    const int w = ctx.extent.width, h = ctx.extent.height;
    const ImageView* outC = io.hasOutput("color") ? &io.output("color") : nullptr;
    const ImageView* outM = io.hasOutput("moments") ? &io.output("moments") : nullptr;
    const ImageView* outH = io.hasOutput("historyLength") ? &io.output("historyLength") : nullptr;
    auto zeroAll = [&] {
        for (const ImageView* o : {outC, outM, outH})
            if (o)
                for (int c = 0; c < o->channels(); ++c)
                    std::fill(o->channel(c), o->channel(c) + o->pixels(), 0.f);
    };
    const bool colorValid = io.hasInput("prevColor"), momentsValid = io.hasInput("prevMoments");
    const bool hlValid = io.hasInput("prevHistoryLength");
    // Without last frame's geometry no tap can be tested; without any history there is nothing
    // to reproject: all outputs 0, history length 0.
    if (!io.hasInput("prevDepth") || !io.hasInput("prevNormal") || (!colorValid && !momentsValid)) {
        zeroAll();
        return;
    }
    const ImageView& depth = io.input("depth");
    const ImageView& normal = io.input("normal");
    const ImageView& pDepth = io.input("prevDepth");
    const ImageView& pNormal = io.input("prevNormal");
    const bool useIds = io.hasInput("objectId") && io.hasInput("prevObjectId");
    const int32_t* curIds = io.hasInput("objectId") ? io.input("objectId").ints() : nullptr;
    const int32_t* ids = useIds ? curIds : nullptr;
    const int32_t* pIds = useIds ? io.input("prevObjectId").ints() : nullptr;
    const ImageView* pColor = colorValid ? &io.input("prevColor") : nullptr;
    const ImageView* pMoments = momentsValid ? &io.input("prevMoments") : nullptr;
    const ImageView* pHist = hlValid ? &io.input("prevHistoryLength") : nullptr;
    const ImageView* motion = io.hasInput("motion") ? &io.input("motion") : nullptr;
    const ImageView* position = io.hasInput("position") ? &io.input("position") : nullptr;
    const bool matrices = !motion && position && ctx.scene && ctx.previousScene &&
                          ctx.scene->hasCamera && ctx.previousScene->hasCamera;
    std::optional<TransformTable> table;
    if (matrices) table.emplace(*ctx.scene, *ctx.previousScene);
    const float dThr = depthThreshold_, nThr = normalThreshold_;
    const bool cr = catmullRom_;

    // Last frame's taps, sanitised once per frame and interleaved per pixel: a consistency
    // test then reads one 20-byte record instead of five planes, and a tap one 24-byte record
    // instead of six (the values are the same sanitised floats the per-tap code computed).
    struct PrevGeom {
        float z, n[3];
        int32_t id;
    };
    struct PrevData {
        float c[3], m[2], h;
    };
    const size_t npx = size_t(w) * size_t(h);
    std::unique_ptr<PrevGeom[]> geomBuf(new PrevGeom[npx]);
    std::unique_ptr<PrevData[]> dataBuf(new PrevData[npx]);
    PrevGeom* const geom = geomBuf.get();
    PrevData* const data = dataBuf.get();
    ctx.parallelRows(h, [&](int ya, int yb) {
        const size_t b = size_t(ya) * size_t(w), e = size_t(yb) * size_t(w);
        const float *pz = pDepth.channel(0), *pn0 = pNormal.channel(0), *pn1 = pNormal.channel(1),
                    *pn2 = pNormal.channel(2);
        for (size_t t = b; t < e; ++t) {
            geom[t].z = px::sanitizeDepth(pz[t]);
            geom[t].n[0] = px::sanitizeNormal(pn0[t]);
            geom[t].n[1] = px::sanitizeNormal(pn1[t]);
            geom[t].n[2] = px::sanitizeNormal(pn2[t]);
            geom[t].id = pIds ? pIds[t] : 0;
        }
        for (size_t t = b; t < e; ++t) {
            for (int c = 0; c < 3; ++c)
                data[t].c[c] = pColor ? px::sanitize(pColor->channel(c)[t]) : 0.f;
            data[t].m[0] = pMoments ? px::sanitize(pMoments->channel(0)[t]) : 0.f;
            data[t].m[1] = pMoments ? px::sanitizePositive(pMoments->channel(1)[t], 1e32f) : 0.f;
            data[t].h = pHist ? px::sanitizePositive(pHist->channel(0)[t], 1e6f) : 1.f;
        }
    });

    ctx.parallelRows(h, [&](int y0, int y1) {
        // This row's screen-space derivatives, computed in a separate loop (per-chunk scratch).
        std::vector<float> rowBuf(size_t(w) * 5);
        float *rInvZ = rowBuf.data(), *rInvN = rInvZ + w, *rn0 = rInvN + w, *rn1 = rn0 + w,
              *rn2 = rn1 + w;
        for (int y = y0; y < y1; ++y) {
            const bool u = y > 0, d = y + 1 < h;
            const int yu = u ? y - 1 : y, yd = d ? y + 1 : y;  // absent neighbours are not used
            rowDerivatives(depth.row(0, y), depth.row(0, yu), depth.row(0, yd), normal.row(0, y),
                           normal.row(0, yu), normal.row(0, yd), normal.row(1, y),
                           normal.row(1, yu), normal.row(1, yd), normal.row(2, y),
                           normal.row(2, yu), normal.row(2, yd), u, d, w, rInvZ, rInvN, rn0, rn1,
                           rn2);
            for (int x = 0; x < w; ++x) {
                const size_t i = size_t(y) * size_t(w) + size_t(x);
                // Previous-frame position in continuous pixel coordinates (centres at +0.5).
                float ppx = float(x) + 0.5f, ppy = float(y) + 0.5f;
                float zRef = px::sanitizeDepth(depth.at(0, x, y));
                bool ok = true;
                if (motion) {
                    ppx += motion->at(0, x, y);
                    ppy += motion->at(1, x, y);
                } else if (matrices) {
                    const int32_t id = curIds ? curIds[i] : 0;
                    if (zRef >= kBackgroundDepth || (curIds && id == kBackgroundId)) {
                        ok = false;  // no surface position to reproject
                    } else {
                        const ObjectTransforms& t = curIds ? table->get(id) : table->fallback();
                        Vec3 p{position->at(0, x, y), position->at(1, x, y), position->at(2, x, y)};
                        Vec4 s = t.toPrevPixel.transformPoint(p);
                        Vec4 c = t.toPrevCamera.transformPoint(p);
                        ok = s.w > 1e-20f;
                        if (ok) {
                            ppx = s.x / s.w;
                            ppy = s.y / s.w;
                            zRef = -c.z;  // the point's depth last frame (camera looks down -Z)
                        }
                    }
                }
                // NaN, Inf or absurd positions: disoccluded (also guards the int conversions).
                ok = ok && std::fabs(ppx) < 1e7f && std::fabs(ppy) < 1e7f;

                const float n[3] = {rn0[x], rn1[x], rn2[x]};
                const float invZ = rInvZ[x], invN = rInvN[x];

                // SVGF consistency test of a previous-frame tap (Falcor's isReprjValid).
                // Reference values hoisted into locals (registers); without prevObjectId every
                // record's id is 0, so the id comparison always holds. Evaluated without early
                // exits: the three tests are pure, so the result is the same.
                const int32_t refId = pIds ? ids[i] : 0;
                const float n0 = n[0], n1 = n[1], n2 = n[2], zR = zRef;
                auto consistent = [&, n0, n1, n2, zR, refId, invZ, invN](int tx, int ty) -> bool {
                    if (unsigned(tx) >= unsigned(w) || unsigned(ty) >= unsigned(h)) return false;
                    const PrevGeom& g = geom[size_t(ty) * size_t(w) + size_t(tx)];
                    const float dz = std::fabs(zR - g.z) * invZ;
                    const float nn[3] = {n0, n1, n2};
                    float dn2 = 0;
                    for (int c = 0; c < 3; ++c) {
                        const float dn = nn[c] - g.n[c];
                        dn2 += dn * dn;
                    }
                    return (g.id == refId) & !(dz > dThr) & (std::sqrt(dn2) * invN <= nThr);
                };

                float acc[3] = {0, 0, 0}, accM[2] = {0, 0}, accH = 0, sumW = 0;
                auto addTap = [&](int tx, int ty, float wt) {
                    const PrevData& d = data[size_t(ty) * size_t(w) + size_t(tx)];
                    if (pColor)
                        for (int c = 0; c < 3; ++c) acc[c] += wt * d.c[c];
                    if (pMoments) {
                        accM[0] += wt * d.m[0];
                        accM[1] += wt * d.m[1];
                    }
                    accH += wt * (pHist ? d.h : 1.f);
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
                    const float bw[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy,
                                         fx * fy};
                    int nOk = 0;
                    for (int k = 0; k < 4; ++k) {
                        const int tx = x0 + (k & 1), ty = y0 + (k >> 1);
                        if (!consistent(tx, ty)) continue;
                        ++nOk;
                        if (bw[k] > 0.f) addTap(tx, ty, bw[k]);
                    }
                    all4 = nOk == 4;
                    if (sumW < 1e-4f) {
                        // 3x3 fallback around the pixel containing the position: equal weights.
                        acc[0] = acc[1] = acc[2] = accM[0] = accM[1] = accH = sumW = 0;
                        const int cx = int(std::floor(ppx)), cy = int(std::floor(ppy));
                        for (int j = -1; j <= 1; ++j)
                            for (int k = -1; k <= 1; ++k)
                                if (consistent(cx + k, cy + j)) addTap(cx + k, cy + j, 1.f);
                        all4 = false;
                    }
                }
                if (sumW <= 0.f) {  // disoccluded
                    if (outC)
                        for (int c = 0; c < 3; ++c) outC->channel(c)[i] = 0.f;
                    if (outM) outM->channel(0)[i] = outM->channel(1)[i] = 0.f;
                    if (outH) outH->channel(0)[i] = 0.f;
                    continue;
                }
                const float inv = 1.f / sumW;
                float col[3] = {acc[0] * inv, acc[1] * inv, acc[2] * inv};
                if (cr && pColor && all4 && x0 >= 1 && y0 >= 1 && x0 + 2 < w && y0 + 2 < h) {
                    // Catmull-Rom 4x4 when every tap is consistent, clamped to the inner 2x2
                    // taps' range so negative lobes cannot ring.
                    bool all16 = true;
                    for (int j = -1; j <= 2 && all16; ++j)
                        for (int k = -1; k <= 2 && all16; ++k)
                            if ((j < 0 || j > 1 || k < 0 || k > 1) && !consistent(x0 + k, y0 + j))
                                all16 = false;
                    if (all16) {
                        float wx[4], wy[4];
                        catmullRomWeights(fx, wx);
                        catmullRomWeights(fy, wy);
                        for (int c = 0; c < 3; ++c) {
                            float s = 0, lo = 3e38f, hi = -3e38f;
                            for (int j = 0; j < 4; ++j)
                                for (int k = 0; k < 4; ++k) {
                                    const float v =
                                        data[size_t(y0 - 1 + j) * size_t(w) + size_t(x0 - 1 + k)]
                                            .c[c];
                                    s += wx[k] * wy[j] * v;
                                    if (j >= 1 && j <= 2 && k >= 1 && k <= 2) {
                                        lo = std::min(lo, v);
                                        hi = std::max(hi, v);
                                    }
                                }
                            col[c] = px::clamp(s, lo, hi);
                        }
                    }
                }
                if (outC)
                    for (int c = 0; c < 3; ++c) outC->channel(c)[i] = col[c];
                if (outM) {
                    outM->channel(0)[i] = accM[0] * inv;
                    outM->channel(1)[i] = accM[1] * inv;
                }
                if (outH) outH->channel(0)[i] = accH * inv;
            }
        }
    });
}
