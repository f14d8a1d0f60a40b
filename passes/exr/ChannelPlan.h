#pragma once
// How each loader output is computed from file channels: a sum of products of channel groups
// ("recipes"), plus a few convention fixes. Layout-specific code (LayoutPlans.cpp) builds a plan
// from the channel names of the first frame; ExrLoader executes it.
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "Absurd.h"
#include "kestrel/Format.h"

namespace kestrel::exr {

enum class Layout { Canonical, Blender, Games202 };
const char* layoutName(Layout l);

/// One channel of one file. `file` is a role ("" for single-file layouts; beauty, normal, ...
/// for GAMES202).
struct ChannelRef {
    std::string file;
    std::string name;
    auto operator<=>(const ChannelRef&) const = default;
    std::string str() const { return file.empty() ? name : file + ":" + name; }
};

/// A factor holds one channel per output channel (3 for Float3).
using Factor = std::vector<ChannelRef>;
/// A term multiplies its factors component-wise; the output sums its terms.
using Term = std::vector<Factor>;

enum class IdRule { Round, BlenderZeroIsBackground };

struct Recipe {
    std::string output;
    Format format = Format::Float3;
    std::vector<Term> terms;
    /// Per channel the output is at most these terms' sum: Blender's emission is at most
    /// Combined (with a transparent film the sky is in Env, not in Combined).
    std::vector<Term> cap;
    /// The light of Combined that no split pass holds: Combined (`color`) less the diffuse and
    /// specular terms (`passes`) and the emission (`emission`, at most Combined). Blender's
    /// split adds its positive part to specular, to be filtered (glass or fog rendered without
    /// their passes, a sky without the Environment pass); where the channels parameter sets
    /// specular, emission takes all of it, kept as it was.
    struct Rest {
        enum class Part { Positive, Whole };
        std::vector<Term> color, passes, emission;
        Part part = Part::Positive;
    };
    std::optional<Rest> rest;
    float scale[4] = {1, 1, 1, 1};  ///< per channel after summing (Blender motion y: -1)
    float fill = 0.f;               ///< where the file has no pixel (outside the data window)
    float lowest = -kAbsurd;        ///< below it a value is damage, replaced by fill (Absurd.h)
    std::optional<ChannelRef> backgroundMask;  ///< GAMES202 depth: where this < -0.5, depth = 1e10
    IdRule idRule = IdRule::Round;             ///< Int32 outputs
    bool zeroIsBackground = false;  ///< depth: values <= 0 (or NaN) are background (1e10)
    bool cameraSpace = false;       ///< normal: camera space, rotated to world by the camera
    /// position: unprojected from the depth channel (its one term) with the frame's camera,
    /// for renders without a Position pass (rayLength: the depth is a distance along the ray,
    /// as Cycles' Denoising Depth, not planar)
    bool fromDepth = false, rayLength = false;
    /// motion: the depth channel that marks the background, where the camera's rotation gives
    /// the motion (Blender writes 0 there even when the camera turns)
    std::optional<ChannelRef> skyDepth;
    /// normal: where the terms read all zero on a surface, this (world space) instead. Cycles'
    /// Denoising Normal is zero where the path passed a mirror or glass to the sky or a light
    /// (8% of the showroom's surfaces): the filters' normal test rejected every neighbour
    /// there, and a pixel kept its 1-spp value (black speckles); the Normal pass gives the
    /// first surface's normal.
    std::optional<Factor> zeroFallback;
    /// reflection: {Cycles' Denoising Normal (camera space), the Normal pass (world space)}: 1
    /// where the first names another surface than the second (the features passed a
    /// near-specular bounce) or none (zero: they reached the sky or a light that way).
    std::optional<std::pair<Factor, Factor>> reflectionOf;
    /// With reflectionOf: 1 only where the first is zero on a surface (the path reached a light
    /// or the sky through the bounce), which needs no camera (lightThroughMirror).
    bool lightOnly = false;
    bool absent = false;
    std::string why;  ///< absent: which channel is missing; present: what is read (for notes)

    bool isDirect() const {
        return terms.size() == 1 && terms[0].size() == 1 && cap.empty() && !rest;
    }
    std::vector<ChannelRef> channels() const;  ///< every channel read (mask included)
};

struct Plan {
    Layout layout = Layout::Canonical;
    std::vector<Recipe> recipes;  ///< one per loader output, in declaration order
    Recipe* find(const std::string& output);
    const Recipe* find(const std::string& output) const;
};

/// Channel names per file role.
using ChannelSets = std::map<std::string, std::set<std::string>>;

/// The loader's outputs (name, format), in declaration order.
struct OutputSpec {
    const char* name;
    Format format;
    float fill;
    const char* description;
    /// The lowest valid value (Absurd.h): 0 for albedos (reflectances), kMostNegativeLight for
    /// light, -kAbsurd for vectors, positions, depth and ids.
    float lowest = -kAbsurd;
};
const std::vector<OutputSpec>& loaderOutputs();
/// The albedo a jittered* output repeats where the render is anti-aliased ("jitteredAlbedo" ->
/// "albedo"), or null for any other output.
const char* jitteredOf(std::string_view output);

Plan planCanonical(const ChannelSets& files);
/// `layer`: the Blender view layer ("ViewLayer"), found by blenderLayer().
Plan planBlender(const ChannelSets& files, const std::string& layer);
Plan planGames202(const ChannelSets& files);
/// A Blender render with the diffuse/specular split: specular (or, where the channels parameter
/// set specular, emission) takes the light no split pass holds (Recipe::Rest), so diffuse +
/// specular + emission = color on every pixel. A canonical file with the split but no emission
/// channel: emission = color - diffuse - specular. Again after the channels parameter changed
/// one of them; `keep`: outputs it set, left alone.
void addSplitRest(Plan& plan, const std::set<std::string>& keep = {});
/// The view layers holding "<layer>.Combined.R", in name order (empty: not a Blender file).
std::vector<std::string> blenderLayers(const std::set<std::string>& channels);

/// Applies the `channels` parameter: "out=EXPR,out=EXPR,..." with EXPR a sum ('+') of products
/// ('*') of channel groups; a group is a layer ("ViewLayer.DiffCol": its R,G,B or X,Y,Z...) or a
/// full channel name; an empty EXPR marks the output absent. In an EXPR of one term a factor may
/// be a constant: a number ("-0.5") or one per channel ("(1,-1)"). "@name" items are presets
/// (ChannelPresets.h). Throws Error naming the item. Returns the outputs it set.
std::set<std::string> applyChannelOverrides(Plan& plan, const std::string& spec,
                                            const ChannelSets& files);

}  // namespace kestrel::exr
