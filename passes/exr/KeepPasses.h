#pragma once
// Keeping the render's passes (ExrWriter parameter keepPasses): the input frame's channels that
// the output does not replace, and its header attributes (camera, frame, render statistics),
// written beside the denoised colour so a compositor keeps its AOVs. The loader states which
// file a frame comes from and which of its channels are the beauty (scene facts, below); the
// writer reads the rest from that file a block of rows at a time, never the whole frame, and
// only reads it.
#include <OpenEXR/ImfHeader.h>

#include <functional>
#include <set>
#include <string>

#include "ChannelPlan.h"
#include "kestrel/FramePattern.h"
#include "kestrel/Pass.h"

namespace kestrel::exr {

/// Scene facts: the loader's frame pattern (single-file layouts only), and the channels its
/// colour and alpha are read from, comma separated.
inline constexpr char kSourcePathFact[] = "sourcePath";
inline constexpr char kSourceColorFact[] = "sourceColorChannels";
inline constexpr char kSourceAlphaFact[] = "sourceAlphaChannels";

/// The loader's side: states the facts above (nothing for GAMES202's file per buffer).
void stateSourceFacts(ResolveContext& rc, const Plan& plan, const FramePattern* pattern);

/// The writer's side, from the facts: where frame N's input is and what the output replaces.
struct KeptSource {
    FramePattern pattern;
    std::set<std::string> color, alpha;  ///< input channels of the colour and the alpha
    /// Throws Error naming keepPasses when no loader stated a single-file source.
    static KeptSource fromFacts(const ResolveContext& rc);
};

/// Fills `dst` with row `y` of the output's own channel `name` (its header type, HALF or FLOAT).
using OwnRow = std::function<void(const std::string& name, int y, void* dst)>;

/// Writes `header` (the output's own channels, which `own` fills) plus the channels of `input`
/// that it does not replace (`replaced`, or a name `header` has) and the input header's
/// attributes (not the structural ones nor those the writer sets, except the chromaticities:
/// the input's replace the output's) to `path`, through OpenEXR, a block of rows at a time. Returns
/// the number of channels kept. Throws Error on a bad input file and what OpenEXR throws on a
/// write.
size_t writeKeepingPasses(const std::string& path, Imf::Header header, const std::string& input,
                          const std::set<std::string>& replaced, const OwnRow& own, int threads);

}  // namespace kestrel::exr
