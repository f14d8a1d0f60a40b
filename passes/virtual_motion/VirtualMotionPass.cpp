#include "VirtualMotionPass.h"

#include <denoise/TapsMask.h>

#include <algorithm>
#include <cmath>
#include <optional>

using namespace kestrel;

VirtualMotionPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "VirtualMotion",
          "Motion of the reflected point's virtual image where the features describe what a "
          "near-specular surface shows (NRD ReBLUR's virtual motion), else the surface motion; "
          "left out (motion forwarded) where the scene lacks reflection or pathLength") {
    motion = input("motion", Format::Float2,
                   "surface motion to the previous frame, pixels, y down (x_prev - x_cur)");
    reflection = optionalInput("reflection", Format::Float,
                               "1 where the features describe what a mirror shows (ExrLoader)");
    pathLength = optionalInput("pathLength", Format::Float,
                               "camera path length through the near-specular bounce (Cycles' "
                               "Denoising Depth; ExrLoader), 0 on the background");
    prevPathLength = historyInput("prevPathLength", Format::Float,
                                  "last frame's pathLength: the virtual image is kept only "
                                  "where it lies at last frame's path length (a planar mirror)");
    taps = optionalInput("taps", Format::Int32,
                         "the surface motion's Reprojection taps, passed on as `taps`");
    // pointwise on motion: each pixel's motion is read before it is written
    motionOut = output("motion", Format::Float2,
                       "the virtual motion where reflection > 0.5 and it is consistent, else the "
                       "input motion",
                       &motion);
    // pointwise on taps, as motion
    tapsOut = output("taps", Format::Int32,
                     "`taps`, with the pixels whose motion this pass moved marked untested "
                     "(denoise/TapsMask.h: a Reprojection fed this motion runs its own "
                     "consistency tests on a frame with any)",
                     &taps);
    param("tolerance", &Params::tolerance, 0.0, 1.0,
          "largest relative difference between the virtual point's distance from last frame's "
          "camera and last frame's path length where it projects (0 keeps the surface motion "
          "wherever the two differ)");
}

const VirtualMotionPass::Declaration& VirtualMotionPass::declaration() {
    static const Declaration d;
    return d;
}

void VirtualMotionPass::resolve(ResolveContext& rc) {
    const Declaration& d = declaration();
    if (rc.isBound(d.reflection) && rc.isBound(d.pathLength)) {
        if (!rc.isBound(d.taps)) rc.setAbsent(d.tapsOut, "no taps given");
        rc.note("virtual motion where reflection is set");
        return;
    }
    const std::string why =
        !rc.isBound(d.reflection) ? rc.unboundReason(d.reflection) : rc.unboundReason(d.pathLength);
    rc.forward(d.motionOut, d.motion);
    if (rc.isBound(d.taps))
        rc.forward(d.tapsOut, d.taps);
    else
        rc.setAbsent(d.tapsOut, "no taps given");
    rc.note("no " + std::string(!rc.isBound(d.reflection) ? "reflection" : "pathLength") +
            (why.empty() ? "" : " (" + why + ")") + ": the surface motion is kept");
}

namespace {

bool usable(float v) {
    return std::isfinite(v) && v > 0.f;
}

/// Whether last frame's path length around pixel position (qx, qy) (its 2x2 bilinear
/// footprint) agrees with `dist` within the relative tolerance: one tap within it, or `dist`
/// between the taps' values where they span no edge (a tenth of dist at most: on a grazing
/// floor the path length changes quickly from pixel to pixel).
bool consistentWith(const ImageView& prev, double qx, double qy, double dist, float tol, int w,
                    int h) {
    if (!(qx >= 0.0 && qy >= 0.0 && qx <= double(w) && qy <= double(h))) return false;
    const int x0 = int(std::floor(qx - 0.5)), y0 = int(std::floor(qy - 0.5));
    double lo = 0, hi = 0;
    bool any = false;
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) {
            const int tx = x0 + i, ty = y0 + j;
            if (tx < 0 || ty < 0 || tx >= w || ty >= h) continue;
            const float t = prev.at(0, tx, ty);
            if (!usable(t)) continue;
            if (std::fabs(double(t) - dist) <= double(tol) * dist) return true;
            lo = any ? std::min(lo, double(t)) : double(t);
            hi = any ? std::max(hi, double(t)) : double(t);
            any = true;
        }
    return any && hi - lo <= 0.1 * dist && dist >= lo * (1.0 - tol) && dist <= hi * (1.0 + tol);
}

}  // namespace

void VirtualMotionPass::execute(FrameContext& ctx, PassIO& io) {
    const Declaration& d = declaration();
    const ImageView &motion = io.input(d.motion), &reflection = io.input(d.reflection),
                    &pathLength = io.input(d.pathLength), &out = io.output(d.motionOut);
    const ImageView* prevLength = io.has(d.prevPathLength) && io.historyValid(d.prevPathLength)
                                      ? &io.input(d.prevPathLength)
                                      : nullptr;
    const bool testHistory = io.has(d.prevPathLength);
    const int w = ctx.extent.width, h = ctx.extent.height;
    // Without both cameras (or with a singular one) there is no virtual image: surface motion.
    std::optional<Mat4> cameraToWorld, prevCameraToWorld;
    if (ctx.scene && ctx.scene->hasCamera && ctx.previousScene && ctx.previousScene->hasCamera) {
        cameraToWorld = inverse(ctx.scene->worldToCamera);
        prevCameraToWorld = inverse(ctx.previousScene->worldToCamera);
    }
    const bool virtualMotion =
        cameraToWorld && prevCameraToWorld && (!testHistory || prevLength != nullptr);
    const Mat4 cameraToPixel =
        virtualMotion ? ctx.scene->worldToPixel * *cameraToWorld : Mat4::identity();
    const Mat4 prevWorldToPixel =
        virtualMotion ? ctx.previousScene->worldToPixel : Mat4::identity();
    const float tol = p_.tolerance;
    const bool passTaps = io.has(d.tapsOut);
    ctx.parallelRows(h, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y) {
            const float *mx = motion.row(0, y), *my = motion.row(1, y);
            const float *refl = reflection.row(0, y), *len = pathLength.row(0, y);
            float *ox = out.row(0, y), *oy = out.row(1, y);
            const int32_t* tapsIn =
                passTaps ? io.input(d.taps).ints() + size_t(y) * size_t(w) : nullptr;
            int32_t* tapsOut =
                passTaps ? io.output(d.tapsOut).ints() + size_t(y) * size_t(w) : nullptr;
            for (int x = 0; x < w; ++x) {
                const float sx = mx[x], sy = my[x];  // read before a write in place
                float vx = sx, vy = sy;
                bool moved = false;
                const float L = len[x];
                if (virtualMotion && refl[x] > 0.5f && usable(L)) {
                    const double px = x + 0.5, py = y + 0.5;
                    double cx, cy;
                    if (pointOnPixelRay(cameraToPixel, px, py, -1.0, cx, cy)) {
                        // The virtual point: the camera ray's unit direction times the path
                        // length, from the eye (the camera-space origin).
                        const double s = double(L) / std::sqrt(cx * cx + cy * cy + 1.0);
                        const double c[4] = {cx * s, cy * s, -s, 1.0};
                        const auto& M = cameraToWorld->m;
                        double p[4] = {0, 0, 0, 1};
                        for (int r = 0; r < 3; ++r) {
                            p[r] = 0;
                            for (int k = 0; k < 4; ++k) p[r] += double(M[r][k]) * c[k];
                        }
                        const auto& P = prevWorldToPixel.m;
                        double q[4] = {0, 0, 0, 0};
                        for (int r = 0; r < 4; ++r)
                            for (int k = 0; k < 4; ++k) q[r] += double(P[r][k]) * p[k];
                        // In front of last frame's camera only (w > 0).
                        if (q[3] > 1e-9 && std::isfinite(q[0]) && std::isfinite(q[1])) {
                            const double qx = q[0] / q[3], qy = q[1] / q[3];
                            bool consistent = std::isfinite(qx) && std::isfinite(qy);
                            if (consistent && prevLength) {
                                // A planar mirror's virtual image stays where it was: its
                                // distance from last frame's eye is last frame's path length
                                // there. A curved mirror's moves: it fails, and the surface
                                // motion is kept (without this test blender-street's curved
                                // chrome lost reflection detail: docs/benchmarks.md section 7).
                                const auto& E = prevCameraToWorld->m;
                                const double ex = p[0] - E[0][3], ey = p[1] - E[1][3],
                                             ez = p[2] - E[2][3];
                                const double dist = std::sqrt(ex * ex + ey * ey + ez * ez);
                                consistent = dist > 0.0 && std::isfinite(dist) &&
                                             consistentWith(*prevLength, qx, qy, dist, tol, w, h);
                            }
                            if (consistent) {
                                const float dx = float(qx - px), dy = float(qy - py);
                                if (std::isfinite(dx) && std::isfinite(dy))
                                    vx = dx, vy = dy, moved = true;
                            }
                        }
                    }
                }
                ox[x] = vx;
                oy[x] = vy;
                if (tapsOut) tapsOut[x] = moved ? taps::kUntested : tapsIn[x];
            }
        }
    });
}
