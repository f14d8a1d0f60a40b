#pragma once
// ExrLoader: the source pass. Reads one frame's AOVs from EXR files in one of three layouts
// (canonical, Blender Cycles multilayer, GAMES202 homework), converting each to the in-memory
// conventions of kestrel/Conventions.h, and reads only the channels a consumer needs.
// Parameters and layouts: docs/layouts.md.
#include <array>
#include <atomic>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "ChannelPlan.h"
#include "ExrInput.h"
#include "LoaderRouting.h"
#include "PixelJitter.h"
#include "SceneMatrices.h"
#include "kestrel/Declare.h"
#include "kestrel/FramePattern.h"
#include "kestrel/Kestrel.h"

namespace kestrel::exr {

class ExrLoader : public Pass {
public:
    enum class LayoutChoice { Auto, Canonical, Blender, Games202 };
    enum class AntiAliasedChoice { Auto, True, False };
    struct Params {
        std::string path;
        LayoutChoice layout = LayoutChoice::Auto;
        std::string layer;
        std::string camera;
        std::string channels;
        AntiAliasedChoice antiAliased = AntiAliasedChoice::Auto;
        int64_t maxPixels = int64_t(1) << 27;
        bool prefetch = false;
    };
    /// Ports and parameters, declared once (kestrel/Declare.h). The outputs are the data of
    /// loaderOutputs() (ChannelPlan.cpp), which the plans build their recipes from.
    struct Declaration : kestrel::Declaration<Params> {
        Declaration();
        /// One per loader output, in declaration order: outputs[k] is Plan::recipes[k]'s.
        std::vector<OutputPort> outputs;
        /// The ones execute reaches by name (specular's rest from the colour, diffuse and
        /// emission planes).
        OutputPort color, diffuse, emission;
    };
    static const Declaration& declaration();

    static PassDesc describe() { return declaration().desc(); }
    explicit ExrLoader(const ParamValues& params);
    ~ExrLoader() override;

    void resolve(ResolveContext& rc) override;
    std::optional<Extent> beginFrame(FrameContext& ctx) override;
    void execute(FrameContext& ctx, PassIO& io) override;
    std::vector<int64_t> availableFrames() const override;
    std::vector<std::pair<std::string, std::string>> filesRead(int64_t frame) const override;
    void beginRun(const RunContext& rc) override;
    void endRun() override;

    /// For tests and logs: the channels the last execute read ("role:name" for GAMES202).
    const std::vector<std::string>& channelsRead() const { return channelsRead_; }
    /// The plan in use (after resolve or the first beginFrame).
    const Plan& plan() const { return plan_; }

private:
    using Notes = std::vector<std::string>;
    static constexpr const char* kGames202Roles[] = {"beauty", "normal", "position", "depth", "ID"};
    void ensurePlan(int64_t frame, Notes* notes);
    /// ensurePlan's steps: which files (GAMES202 or one per frame; sets pattern_), the frame
    /// probed, the plan of each layout, and the plan's adaptations to what the render lacks.
    bool choosePattern(std::string& pattern, bool& namedLikeBeauty);
    int64_t probedFrame(int64_t frame, const std::string& pattern, Notes& notes) const;
    void planGames202Files(int64_t first, const std::string& firstPath, ChannelSets& sets,
                           Notes& notes);
    std::unique_ptr<ExrInput> planSingleFile(int64_t first, const std::string& firstPath,
                                             ChannelSets& sets, Notes& notes);
    void planBlenderFile(const std::string& firstPath, const std::vector<std::string>& layers,
                         const ChannelSets& sets, Notes& notes);
    void adaptPlan(ExrInput* probed, int64_t first, const ChannelSets& sets, Notes& notes);
    /// The output handle of a recipe of plan_ (the same place in the declaration).
    const OutputPort& port(const Recipe* r) const;
    const ImageView& output(PassIO& io, const Recipe* r) const { return io.output(port(r)); }
    float* plane(PassIO& io, const Routing::Slot& s) const;
    /// execute's steps.
    const Routing& routingFor(const PassIO& io);
    void bindPlanes(PassIO& io, const Routing& rt, size_t N);
    size_t decode(FrameContext& ctx, PassIO& io, const Routing& rt,
                  std::map<ChannelRef, std::atomic<size_t>>& replaced);
    void computeComposites(FrameContext& ctx, PassIO& io, const Routing& rt,
                           const std::vector<Deferred>& deferred,
                           std::vector<std::array<std::atomic<size_t>, 4>>& compositeReplaced);
    void computeDerived(FrameContext& ctx, PassIO& io, const Routing& rt, int W, int H);
    void applyConventions(FrameContext& ctx, PassIO& io, const Routing& rt, size_t N);
    std::vector<std::pair<std::string, size_t>> replacedByOutput(
        FrameContext& ctx, PassIO& io, const Routing& rt,
        const std::vector<std::array<std::atomic<size_t>, 4>>& compositeReplaced,
        const std::map<ChannelRef, std::atomic<size_t>>& decoded, int W, int H) const;
    void logChannels(size_t N, size_t fileBytes);
    std::string filePath(const std::string& role, int64_t frame) const;
    ExrInput& openRole(const std::string& role, int64_t frame);
    /// Throws FrameError naming the file and frame when this frame's size is not the first
    /// frame's: history of one size cannot filter a frame of another.
    void checkFrameSize(const ExrInput& in) const;
    void rememberFirstFrame(int64_t frame, const ExrInput& in);
    /// The one warning of a frame whose NaN, infinite and absurd values were replaced by each
    /// output's fill value (Absurd.h, docs/errors.md): counts by output channel ("color.R").
    void warnReplaced(const std::vector<std::pair<std::string, size_t>>& replaced) const;
    void fillScene(int64_t frame, SceneData& scene);
    /// Throws Error naming camera.json and the first input frame in the run it lists no entry for.
    void checkCameraFrames(int64_t firstFrame) const;
    std::string cameraGap(const std::vector<int64_t>& frames) const;
    /// The jittered* outputs: their albedo's recipe where the render is anti-aliased
    /// (PixelJitter.h, decided once); an output the channels parameter set stays as set.
    /// `first`: the probed first file (null for GAMES202), read again for its depth only when
    /// the render does not state its pixel filter.
    void planAntiAliasing(ExrInput* first, const std::set<std::string>& overridden);
    AntiAliasing antiAliasing_;  ///< decided once per run (the "antiAliased" scene fact)
    /// Blender: background motion from the cameras (the Vector pass holds 0 there).
    void planSkyMotion();
    void skyMotion(FrameContext& ctx, const float* depth, const ImageView& motion, int W,
                   int H) const;
    /// Whether the frames come with a camera: camera.json, or the canonical file's matrices.
    bool hasCamera(const ExrInput* first) const;
    /// position from depth and the camera where the render has no position channels.
    void planPositionFromDepth(const ExrInput* first);
    void unprojectDepth(FrameContext& ctx, const float* depth, bool rayLength, const ImageView& out,
                        int W, int H) const;
    /// normal reconstructed from depth where the render has no normal pass: with the camera,
    /// else in camera space from an assumed field of view (kAssumedFieldOfView).
    void planNormalFromDepth(const ExrInput* first);
    void normalsFromDepth(FrameContext& ctx, const float* depth, bool rayLength,
                          const ImageView& out, int W, int H) const;
    std::optional<float> statedFilterWidth(const ExrInput* first) const;
    /// Whether every channel an output reads is half in the first frame (GAMES202: its file).
    bool storedAsHalf(const std::string& output, const ExrInput* first, int64_t frame) const;
    std::optional<float> measureDepthJitter(ExrInput* first) const;

    /// Decoded file channels of one frame, read ahead on a background thread while the graph
    /// computes the frame before it (parameter "prefetch").
    struct Prefetch {
        int64_t frame = 0;
        std::vector<std::pair<std::string, std::unique_ptr<ExrInput>>> open;
        std::map<ChannelRef, PlaneStorage> planes;
        std::map<ChannelRef, std::atomic<size_t>> replaced;  // absurd values, per channel
        bool ok = false;  // false: any failure; the frame is then read as without prefetch
    };
    /// `direct`: the channels decoded straight into an output, whose absurd values the
    /// decoder replaces (Absurd.h), each with its output's lowest valid value.
    void startPrefetch(int64_t frame, const std::map<ChannelRef, float>& fills,
                       const std::map<ChannelRef, float>& direct);
    void joinPrefetch();

    Params p_;
    int threads_ = 1;  // the engine's, for decoding (set by beginFrame)

    // compile-time state (from the first frame; immutable while frames run)
    bool planned_ = false;
    Plan plan_;
    std::unique_ptr<FramePattern> pattern_;   // the single file, or GAMES202's beauty file
    std::string games202Dir_, games202Tail_;  // "dir/" and "_%d.exr" around the role name
    std::unique_ptr<BlenderCameras> cameras_;
    bool games202Matrices_ = false;
    bool colorHalf_ = false;  // every channel of the colour is stored as half
    bool depthHalf_ = false;  // the depth channel is stored as half
    struct FirstFrame {
        int64_t frame = 0;
        std::string path;
        int64_t width = 0, height = 0;
    };
    FirstFrame firstFrame_;  // the probed first frame: every frame must have its size

    // this frame's open files (headers read in beginFrame / on first use)
    int64_t frame_ = 0;
    std::vector<std::pair<std::string, std::unique_ptr<ExrInput>>> open_;
    Box display_;

    // Which file channel feeds which output, with which conversion: built once per run, on the
    // first frame (again only if another set of outputs is consumed: unit tests).
    std::unique_ptr<Routing> routing_;
    Planes planes_;  // the routing's channels' planes this frame (keys fixed with the routing)

    // private scratch: planes for channels that feed sums and products
    std::vector<PlaneStorage> scratch_;
    size_t scratchPixels_ = 0;
    std::vector<std::string> channelsRead_;
    bool logged_ = false;

    // read-ahead state
    std::future<void> prefetchJob_;
    std::unique_ptr<Prefetch> pending_;         // written by the job until joined
    std::unique_ptr<Prefetch> ready_;           // the prefetched frame beginFrame adopted
    std::map<ChannelRef, PlaneStorage> spare_;  // planes reused by the next prefetch
    size_t spareN_ = 0;                         // their size (pixels)
    std::atomic<bool> cancel_{false};
    int64_t lastFrame_ = INT64_MAX, step_ = 1;
    bool haveLast_ = false;
};

}  // namespace kestrel::exr
