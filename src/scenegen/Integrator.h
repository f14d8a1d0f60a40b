#pragma once
// Path tracing with next-event estimation (area light + glowing sphere) on Lambertian surfaces.
#include "Random.h"
#include "Scene.h"

namespace kestrel::scenegen {

struct SurfacePoint {
    V3 p, n, albedo;  // n: unit, facing the incoming ray
};

struct PathRadiance {
    V3 direct;    // NEE at the first hit
    V3 indirect;  // NEE at the later vertices
};

/// One path from a first hit: its direct and indirect radiance (emission of the first hit not
/// included). Emitters are only reached by NEE (BSDF-sampled hits on emitters end the path with
/// nothing), which is unbiased because every emitter is sampled by NEE.
PathRadiance tracePath(const SceneState& s, const SurfacePoint& first, int indirectBounces,
                       Rng& rng);

/// Primary ray through the centre of pixel (i, j) (no jitter): world direction, unit.
V3 primaryDirection(const Camera& c, int i, int j);

/// First-hit surface description; false when the hit is an emitter or nothing.
SurfacePoint makeSurfacePoint(const Hit& hit, V3 p, V3 rayDir);

}  // namespace kestrel::scenegen
