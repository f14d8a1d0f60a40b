// The loader's outputs derived from other channels with the frame's camera: positions and
// normals from depth (renders without those passes), the sky's motion from the cameras'
// rotation (Blender), and the reflection masks.
#include <kestrel/PixelMath.h>

#include <algorithm>
#include <array>
#include <limits>
#include <optional>

#include "ExrLoader.h"
#include "LoaderDecode.h"
#include "SceneMatrices.h"
#include "Unproject.h"

namespace kestrel::exr {

namespace {

/// Recipe::reflectionOf: 1 where Cycles' Denoising Normal (camera space, read before the
/// convention fixes turn it) is zero on a surface or more than ~8 degrees from the Normal pass
/// (world space, turned to camera space here), else 0. Without a camera this frame: 0.
void reflectionMask(FrameContext& ctx, const std::pair<Factor, Factor>& of, const Planes& dest,
                    const ImageView& out, size_t n) {
    float* o = asFloats(out, 0);
    if (!ctx.scene || !ctx.scene->hasCamera) {
        std::fill(o, o + n, 0.f);
        return;
    }
    const auto& m = ctx.scene->worldToCamera.m;
    const float* d[3] = {dest.at(of.first[0]), dest.at(of.first[1]), dest.at(of.first[2])};
    const float* g[3] = {dest.at(of.second[0]), dest.at(of.second[1]), dest.at(of.second[2])};
    for (size_t i = 0; i < n; ++i) {
        const float gx = px::sanitizeNormal(g[0][i]), gy = px::sanitizeNormal(g[1][i]),
                    gz = px::sanitizeNormal(g[2][i]);
        // World to Cycles' camera space (x right, y up, z forward: rotateToWorld's inverse).
        const float cx = m[0][0] * gx + m[0][1] * gy + m[0][2] * gz;
        const float cy = m[1][0] * gx + m[1][1] * gy + m[1][2] * gz;
        const float cz = -(m[2][0] * gx + m[2][1] * gy + m[2][2] * gz);
        const float dx = px::sanitizeNormal(d[0][i]), dy = px::sanitizeNormal(d[1][i]),
                    dz = px::sanitizeNormal(d[2][i]);
        const bool surface = gx != 0.f || gy != 0.f || gz != 0.f;
        const bool none = dx == 0.f && dy == 0.f && dz == 0.f;
        o[i] = surface && (none || dx * cx + dy * cy + dz * cz < 0.99f) ? 1.f : 0.f;
    }
}

/// Recipe::lightOnly: 1 where Cycles' Denoising Normal is zero and the Normal pass is not (the
/// path reached a light or the sky through a near-specular bounce), else 0; no camera needed.
/// The Denoising Normal must be exactly zero (read raw: a damaged NaN or Inf is not a view of a
/// light, and KeepExact would keep that pixel's 1-spp colour).
void lightThroughMirrorMask(const std::pair<Factor, Factor>& of, const Planes& planes,
                            const ImageView& out, size_t n) {
    float* o = asFloats(out, 0);
    const float* d[3] = {planes.at(of.first[0]), planes.at(of.first[1]), planes.at(of.first[2])};
    const float* g[3] = {planes.at(of.second[0]), planes.at(of.second[1]), planes.at(of.second[2])};
    auto exactlyZero = [&](size_t i) { return d[0][i] == 0.f && d[1][i] == 0.f && d[2][i] == 0.f; };
    auto surface = [&](size_t i) {
        return px::sanitizeNormal(g[0][i]) != 0.f || px::sanitizeNormal(g[1][i]) != 0.f ||
               px::sanitizeNormal(g[2][i]) != 0.f;
    };
    for (size_t i = 0; i < n; ++i) o[i] = exactlyZero(i) && surface(i) ? 1.f : 0.f;
}

}  // namespace

void ExrLoader::unprojectDepth(FrameContext& ctx, const float* depth, bool rayLength,
                               const ImageView& out, int W, int H) const {
    const size_t N = size_t(W) * size_t(H);
    std::optional<Mat4> cameraToWorld;
    if (ctx.scene && ctx.scene->hasCamera) cameraToWorld = inverse(ctx.scene->worldToCamera);
    if (!cameraToWorld) {  // this frame has no camera: no positions (Reprojection: disocclusion)
        for (int c = 0; c < 3; ++c) fillPlane(asFloats(out, c), N, 0.f);
        return;
    }
    const Mat4 cameraToPixel = ctx.scene->worldToPixel * *cameraToWorld;
    ctx.parallelRows(H, [&](int y0, int y1) {
        unprojectRows(cameraToPixel, *cameraToWorld, depth, rayLength,
                      {asFloats(out, 0), asFloats(out, 1), asFloats(out, 2)}, W, y0, y1);
    });
}

void ExrLoader::skyMotion(FrameContext& ctx, const float* depth, const ImageView& motion, int W,
                          int H) const {
    if (!cameras_) {  // the sky's motion is unknown: no history is reused there
        const float unknown = std::numeric_limits<float>::quiet_NaN();
        float *mx = asFloats(motion, 0), *my = asFloats(motion, 1);
        ctx.parallelRows(H, [&](int y0, int y1) {
            for (size_t i = size_t(y0) * size_t(W); i < size_t(y1) * size_t(W); ++i)
                if (!(depth[i] > 0.f) || depth[i] >= 1e9f) mx[i] = my[i] = unknown;
        });
        return;
    }
    SceneData prev;
    if (!ctx.scene || !ctx.scene->hasCamera || !cameras_->fill(frame_ - 1, prev) || !prev.hasCamera)
        return;  // no previous camera (the shot's first frame): Blender's 0 stays
    const std::optional<Mat4> cameraToWorld = inverse(ctx.scene->worldToCamera);
    if (!cameraToWorld) return;
    const Mat4 cameraToPixel = ctx.scene->worldToPixel * *cameraToWorld;
    ctx.parallelRows(H, [&](int y0, int y1) {
        skyMotionRows(cameraToPixel, *cameraToWorld, prev.worldToPixel, depth,
                      {asFloats(motion, 0), asFloats(motion, 1)}, W, y0, y1);
    });
}

void ExrLoader::normalsFromDepth(FrameContext& ctx, const float* depth, bool rayLength,
                                 const ImageView& out, int W, int H) const {
    const size_t N = size_t(W) * size_t(H);
    std::optional<Mat4> cameraToWorld;
    if (ctx.scene && ctx.scene->hasCamera) cameraToWorld = inverse(ctx.scene->worldToCamera);
    // A frame without a camera: normals in camera space from an assumed field of view. Under
    // a wrong focal length a planar depth unprojects to the true surface scaled across the view
    // axis, so a plane stays a plane with one normal, and the filters' normal test still
    // parts creases (the normals lean, which no test between two pixels sees). A ray-length
    // depth (Denoising Depth) bends slightly instead: each ray's direction is off by its own
    // amount.
    const Mat4 cameraToPixel = cameraToWorld ? ctx.scene->worldToPixel * *cameraToWorld
                                             : perspectiveToPixel(kAssumedFieldOfView, W, H);
    if (!cameraToWorld) cameraToWorld = Mat4::identity();
    // Positions of the whole frame first (a transient 12 B/px, only on renders without a
    // normal pass): each pixel's normal reads its neighbours'.
    std::vector<float> pos(3 * N);
    const std::array<float*, 3> p = {pos.data(), pos.data() + N, pos.data() + 2 * N};
    ctx.parallelRows(H, [&](int y0, int y1) {
        unprojectRows(cameraToPixel, *cameraToWorld, depth, rayLength, p, W, y0, y1);
    });
    const auto& M = cameraToWorld->m;
    const double eye[3] = {M[0][3], M[1][3], M[2][3]};
    ctx.parallelRows(H, [&](int y0, int y1) {
        normalsFromPositionsRows({p[0], p[1], p[2]}, depth, eye,
                                 {asFloats(out, 0), asFloats(out, 1), asFloats(out, 2)}, W, H, y0,
                                 y1);
    });
}

void ExrLoader::computeDerived(FrameContext& ctx, PassIO& io, const Routing& rt, int W, int H) {
    // Positions unprojected from raw depth (before depth's own background convention).
    for (const Recipe* r : rt.derived) {
        if (r->reflectionOf) continue;  // reflectionMask, below
        const float* depth = planes_.at(r->terms[0][0][0]);
        if (r->output == "normal")
            normalsFromDepth(ctx, depth, r->rayLength, output(io, r), W, H);
        else
            unprojectDepth(ctx, depth, r->rayLength, output(io, r), W, H);
    }
    const size_t N = size_t(W) * size_t(H);
    for (const Recipe* r : rt.active) {
        if (r->reflectionOf && r->lightOnly)
            lightThroughMirrorMask(*r->reflectionOf, planes_, output(io, r), N);
        else if (r->reflectionOf)
            reflectionMask(ctx, *r->reflectionOf, planes_, output(io, r), N);
    }
}

}  // namespace kestrel::exr
