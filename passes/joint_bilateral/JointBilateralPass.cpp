#include "JointBilateralPass.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "JbfMath.h"

namespace kestrel::passes {

namespace {

constexpr float kMaxColor = 1e18f;     // sums of 4000+ weighted taps stay finite
constexpr float kMaxPosition = 1e15f;  // |P_j - P_i|^2 stays finite
constexpr float kBackgroundIdF = float(kBackgroundId);
constexpr int kChunk = 64;      // centre pixels processed together (tiles stay in L1)
constexpr int kMaxRadius = 64;  // the radius parameter's upper bound

// NaN and +-Inf carry no information: 0, as px::sanitize does (clamping Inf to +-limit made one
// Inf sample a 1e18 output that the temporal history then kept; stability suite,
// NanAndInfRadiance).
float sanitise(float v, float limit) {
    return std::isfinite(v) ? std::clamp(v, -limit, limit) : 0.f;
}

/// Per-pixel terms of the guide, planar, with `pad` background columns on the left and
/// pad + kChunk on the right, so the tap loop needs no border tests and always runs over whole
/// chunks: colour, unit normal, position, id (-1 for background/padding).
struct GuidePlanes {
    enum { R, G, B, NX, NY, NZ, PX, PY, PZ, ID, Count };
    int width = 0, height = 0, pad = 0, stride = 0;
    std::vector<float> data;

    GuidePlanes(int w, int h, int p)
        : width(w),
          height(h),
          pad(p),
          stride(w + 2 * p + kChunk),
          data(size_t(Count) * stride * h, 0.f) {
        float* ids = data.data() + size_t(ID) * stride * h;
        std::fill(ids, ids + size_t(stride) * h, kBackgroundIdF);
    }
    float* row(int plane, int y) {
        return data.data() + (size_t(plane) * height + y) * stride + pad;
    }
    const float* row(int plane, int y) const {
        return data.data() + (size_t(plane) * height + y) * stride + pad;
    }
};

void buildGuide(FrameContext& ctx, PassIO& io, GuidePlanes& g) {
    const JointBilateralPass::Declaration& d = JointBilateralPass::declaration();
    const ImageView& color = io.input(d.color);
    const ImageView& normal = io.input(d.normal);
    const ImageView& position = io.input(d.position);
    const ImageView* depth = io.has(d.depth) ? &io.input(d.depth) : nullptr;
    const ImageView* ids = io.has(d.objectId) ? &io.input(d.objectId) : nullptr;
    const int w = g.width;
    ctx.parallelRows(g.height, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
            float* o[GuidePlanes::Count];
            for (int k = 0; k < GuidePlanes::Count; ++k) o[k] = g.row(k, y);
            for (int x = 0; x < w; ++x) {
                for (int c = 0; c < 3; ++c)
                    o[GuidePlanes::R + c][x] = sanitise(color.at(c, x, y), kMaxColor);
                const float nx = normal.at(0, x, y), ny = normal.at(1, x, y),
                            nz = normal.at(2, x, y);
                const float n2 = nx * nx + ny * ny + nz * nz;
                const float px = position.at(0, x, y), py = position.at(1, x, y),
                            pz = position.at(2, x, y);
                bool background = !(n2 > 1e-12f) || !std::isfinite(n2) || !std::isfinite(px) ||
                                  !std::isfinite(py) || !std::isfinite(pz);
                if (depth)
                    background = background || !(depth->at(0, x, y) < 0.5f * kBackgroundDepth);
                float id = 0.f;
                if (ids) {
                    const int32_t v = ids->atInt(x, y);
                    background = background || v == kBackgroundId;
                    id = float(v);  // exact for |id| < 2^24
                }
                const float inv = background ? 0.f : 1.f / std::sqrt(n2);
                o[GuidePlanes::NX][x] = nx * inv;
                o[GuidePlanes::NY][x] = ny * inv;
                o[GuidePlanes::NZ][x] = nz * inv;
                o[GuidePlanes::PX][x] =
                    background ? 0.f : std::clamp(px, -kMaxPosition, kMaxPosition);
                o[GuidePlanes::PY][x] =
                    background ? 0.f : std::clamp(py, -kMaxPosition, kMaxPosition);
                o[GuidePlanes::PZ][x] =
                    background ? 0.f : std::clamp(pz, -kMaxPosition, kMaxPosition);
                o[GuidePlanes::ID][x] = background ? kBackgroundIdF : id;
            }
        }
    });
}

/// Filters centres [x0, x0 + n) of row y. The tap loop runs over kChunk centres for one
/// (dx, dy) offset at a time: contiguous loads, no reductions, so it vectorises across centres.
/// The centres and the neighbour row segment are first copied into small local tiles with
/// compile-time plane pitches, so the loop addresses everything from one or two registers
/// (with 20+ separate plane pointers GCC spills them and reloads every iteration).
/// ExactObtuse: false when an angle >= pi/2 alone already drives the weight to 0, so acos^2 can
/// be evaluated without a square root (jbf::acosSquaredAcute); true evaluates it for all angles.
template <bool ExactObtuse>
void filterChunk(const GuidePlanes& g, const JointBilateralPass::Settings& s, int y, int x0, int n,
                 float* outR, float* outG, float* outB) {
    constexpr int P = GuidePlanes::Count;
    constexpr int kPitch = kChunk + 2 * kMaxRadius;
    alignas(64) float c[P][kChunk];
    alignas(64) float q[P][kPitch];
    alignas(64) float acc[4][kChunk] = {};
    const int r = s.radius;
    for (int k = 0; k < P; ++k) std::copy_n(g.row(k, y) + x0, kChunk, c[k]);
    const float kc = s.invTwoSigmaColor2, kn = s.invTwoSigmaNormal2, kd = s.invTwoSigmaPlane2;
    enum { R, G, B, NX, NY, NZ, PX, PY, PZ, ID };

    for (int yy = std::max(0, y - r); yy <= std::min(g.height - 1, y + r); ++yy) {
        const int dy = yy - y;
        const float* ids = g.row(GuidePlanes::ID, yy) + x0 - r;
        if (std::all_of(ids, ids + kChunk + 2 * r, [](float v) { return v == kBackgroundIdF; }))
            continue;  // background contributes nothing
        for (int k = 0; k < P; ++k) std::copy_n(g.row(k, yy) + x0 - r, kChunk + 2 * r, q[k]);
        for (int o = 0; o <= 2 * r; ++o) {  // o = dx + r
            const int dx = o - r;
            const float spatial = float(dx * dx + dy * dy) * s.invTwoSigmaCoord2;
            for (int i = 0; i < kChunk; ++i) {
                const int j = o + i;
                const float dr = q[R][j] - c[R][i], dg = q[G][j] - c[G][i], db = q[B][j] - c[B][i];
                const float color2 = dr * dr + dg * dg + db * db;
                const float cosN = c[NX][i] * q[NX][j] + c[NY][i] * q[NY][j] + c[NZ][i] * q[NZ][j];
                const float normal2 =
                    ExactObtuse ? jbf::acosSquared(cosN) : jbf::acosSquaredAcute(cosN);
                const float ex = q[PX][j] - c[PX][i], ey = q[PY][j] - c[PY][i],
                            ez = q[PZ][j] - c[PZ][i];
                const float nd = c[NX][i] * ex + c[NY][i] * ey + c[NZ][i] * ez;
                const float dd = ex * ex + ey * ey + ez * ez;
                // D_plane^2 = nd^2 / dd; nd = 0 whenever dd = 0, so the floor makes it 0 there.
                const float plane2 = nd * nd / std::max(dd, 1e-30f);
                const float e = spatial + color2 * kc + normal2 * kn + plane2 * kd;
                float wgt = jbf::exp2NonPositive(-e);  // constants carry log2(e)
                wgt = q[ID][j] == c[ID][i] ? wgt : 0.f;
                acc[0][i] += wgt * q[R][j];
                acc[1][i] += wgt * q[G][j];
                acc[2][i] += wgt * q[B][j];
                acc[3][i] += wgt;
            }
        }
    }
    for (int i = 0; i < n; ++i) {
        // Background centres pass through; a foreground centre has weight ~1 on itself.
        // Divisions (not a reciprocal) so a constant neighbourhood reproduces its value exactly.
        const bool keep = c[ID][i] == kBackgroundIdF || !(acc[3][i] > 0.f);
        const float wsum = keep ? 1.f : acc[3][i];
        outR[i] = keep ? c[R][i] : acc[0][i] / wsum;
        outG[i] = keep ? c[G][i] : acc[1][i] / wsum;
        outB[i] = keep ? c[B][i] : acc[2][i] / wsum;
    }
}

}  // namespace

JointBilateralPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "JointBilateral",
          "GAMES202 joint bilateral filter guided by normal, position and object id") {
    color = input("color", Format::Float3, "noisy colour");
    normal = input("normal", Format::Float3, "world-space unit normal ((0,0,0) on background)");
    position = input("position", Format::Float3, "world-space position (D_plane term)");
    depth = optionalInput("depth", Format::Float, "linear depth: only marks background pixels");
    objectId =
        optionalInput("objectId", Format::Int32, "object id: taps of other objects get weight 0");
    colorOut = output("color", Format::Float3, "filtered colour");
    param("sigmaCoord", &Params::sigmaCoord, 0.01, 1e4, "spatial sigma in pixels (sigma_p)");
    param("sigmaColor", &Params::sigmaColor, 1e-4, 1e6, "colour-distance sigma (sigma_c)");
    param("sigmaNormal", &Params::sigmaNormal, 1e-4, 1e3,
          "normal-angle sigma in radians (sigma_n)");
    param("sigmaPlane", &Params::sigmaPlane, 1e-4, 1e3, "D_plane sigma (sigma_d)");
    param("radius", &Params::radius, 0, kMaxRadius, "kernel radius in pixels ((2r+1)^2 taps)");
}

const JointBilateralPass::Declaration& JointBilateralPass::declaration() {
    static const Declaration d;
    return d;
}

JointBilateralPass::JointBilateralPass(const ParamValues& params) {
    const Params p = declaration().read(params);
    // 1 / (2 sigma^2), times log2(e): the kernel evaluates exp(-x) as 2^(-x log2 e).
    auto inv = [](double sigma) { return float(1.4426950408889634 / (2.0 * sigma * sigma)); };
    s_.radius = p.radius;
    s_.invTwoSigmaCoord2 = inv(p.sigmaCoord);
    s_.invTwoSigmaColor2 = inv(p.sigmaColor);
    s_.invTwoSigmaNormal2 = inv(p.sigmaNormal);
    s_.invTwoSigmaPlane2 = inv(p.sigmaPlane);
}

void JointBilateralPass::execute(FrameContext& ctx, PassIO& io) {
    const ImageView& out = io.output(declaration().colorOut);
    const int w = out.width(), h = out.height();
    GuidePlanes guide(w, h, s_.radius);
    buildGuide(ctx, io, guide);

    // An angle of pi/2 alone contributes (pi/2)^2 / (2 sn^2) log2(e) to the (base-2) exponent;
    // from 126 on the weight is exactly 0 in jbf::exp2NonPositive, so obtuse angles need no
    // exact acos (true for the default sigmaNormal 0.1: 178 > 126).
    const float halfPi2 = 2.4674011f;
    const bool exactObtuse = halfPi2 * s_.invTwoSigmaNormal2 < 126.5f;
    const Settings s = s_;
    ctx.parallelRows(h, [&](int y0, int y1) {
        // Chunk columns outside, rows inside: consecutive rows of one column reuse the same
        // (2r+1)-row window of guide data from L2 (whole guide rows would come from L3).
        for (int x0 = 0; x0 < w; x0 += kChunk) {
            for (int y = y0; y < y1; ++y) {
                const float* id = guide.row(GuidePlanes::ID, y);
                const int n = std::min(kChunk, w - x0);
                float* oR = out.row(0, y) + x0;
                float* oG = out.row(1, y) + x0;
                float* oB = out.row(2, y) + x0;
                if (std::all_of(id + x0, id + x0 + n,
                                [](float v) { return v == kBackgroundIdF; })) {
                    for (int i = 0; i < n; ++i) {
                        oR[i] = guide.row(GuidePlanes::R, y)[x0 + i];
                        oG[i] = guide.row(GuidePlanes::G, y)[x0 + i];
                        oB[i] = guide.row(GuidePlanes::B, y)[x0 + i];
                    }
                    continue;
                }
                if (exactObtuse)
                    filterChunk<true>(guide, s, y, x0, n, oR, oG, oB);
                else
                    filterChunk<false>(guide, s, y, x0, n, oR, oG, oB);
            }
        }
    });
}

}  // namespace kestrel::passes
