// The loader's convention fixes, in place after the outputs are computed: scales (motion y),
// background depth, camera-space normals turned to world space, zero normals' fallback, the
// sky's motion, then ids to int32.
#include "LoaderConventions.h"

#include <cmath>
#include <cstdint>
#include <cstring>

#include "ExrLoader.h"
#include "LoaderDecode.h"

namespace kestrel::exr {

namespace {

/// Cycles' camera-space directions (x right, y up, z forward: measured on blender-street, where
/// the ground's Denoising Normal is (0, 0.989, 0.151) under a view whose up row is
/// (.., 0.989, -0.151)) to world space: z flipped to the OpenGL view's (looking down -z), then
/// by the transpose of the view's rotation (orthonormal for Blender's cameras). The
/// background's zero vectors stay zero.
void rotateToWorld(const Mat4& worldToCamera, const ImageView& v, size_t n) {
    const auto& m = worldToCamera.m;
    float *x = asFloats(v, 0), *y = asFloats(v, 1), *z = asFloats(v, 2);
    for (size_t i = 0; i < n; ++i) {
        const float cx = x[i], cy = y[i], cz = -z[i];
        x[i] = m[0][0] * cx + m[1][0] * cy + m[2][0] * cz;
        y[i] = m[0][1] * cx + m[1][1] * cy + m[2][1] * cz;
        z[i] = m[0][2] * cx + m[1][2] * cy + m[2][2] * cz;
    }
}

/// Where all three channels of `out` are zero, the fallback's channels reversed
/// (Recipe::zeroFallback): the sky or light a mirror shows is filtered with itself, across the
/// mirror, and never with the mirror's frame or the wall around it, whose normal is the
/// fallback's own (dot -1: every normal test rejects it).
void fillZeroVectors(const Factor& fallback, const Planes& dest, const ImageView& out, size_t n) {
    float* o[3] = {asFloats(out, 0), asFloats(out, 1), asFloats(out, 2)};
    const float* f[3] = {dest.at(fallback[0]), dest.at(fallback[1]), dest.at(fallback[2])};
    for (size_t i = 0; i < n; ++i)
        if (o[0][i] == 0.f && o[1][i] == 0.f && o[2][i] == 0.f)
            for (int c = 0; c < 3; ++c) o[c][i] = -f[c][i];
}

}  // namespace

void floatsToIds(float* plane, size_t n, IdRule rule) {
    for (size_t i = 0; i < n; ++i) {
        float v;
        std::memcpy(&v, plane + i, 4);
        int32_t id = kBackgroundId;
        if (rule == IdRule::BlenderZeroIsBackground) {
            if (v >= 0.5f && v < 2.1e9f) id = int32_t(std::lround(v));  // IndexOB: 0 = background
        } else if (v > -0.5f && v < 2.1e9f) {
            id = int32_t(std::lround(v));
        }
        std::memcpy(plane + i, &id, 4);
    }
}

void ExrLoader::applyConventions(FrameContext& ctx, PassIO& io, const Routing& rt, size_t N) {
    const int W = int(display_.width()), H = int(display_.height());
    for (const Recipe* r : rt.active) {
        const ImageView& out = output(io, r);
        for (int c = 0; c < channelCount(r->format); ++c)
            if (r->scale[c] != 1.f && r->format != Format::Int32) {
                float* o = asFloats(out, c);
                const float s = r->scale[c];
                for (size_t i = 0; i < N; ++i) o[i] *= s;
            }
        if (r->backgroundMask) {
            const float* m = planes_.at(*r->backgroundMask);
            float* o = asFloats(out, 0);
            for (size_t i = 0; i < N; ++i)
                if (!(m[i] > -0.5f)) o[i] = kBackgroundDepth;
        }
        if (r->zeroIsBackground) {
            float* o = asFloats(out, 0);
            for (size_t i = 0; i < N; ++i)
                if (!(o[i] > 0.f)) o[i] = kBackgroundDepth;
        }
        if (r->cameraSpace && ctx.scene && ctx.scene->hasCamera)
            rotateToWorld(ctx.scene->worldToCamera, out, N);
        if (r->zeroFallback) fillZeroVectors(*r->zeroFallback, planes_, out, N);
    }
    for (const Recipe* r : rt.active)
        if (r->skyDepth) skyMotion(ctx, planes_.at(*r->skyDepth), output(io, r), W, H);
    for (const Recipe* r : rt.active)
        if (r->format == Format::Int32) floatsToIds(asFloats(output(io, r), 0), N, r->idRule);
}

}  // namespace kestrel::exr
