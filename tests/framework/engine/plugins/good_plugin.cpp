// A well-formed test plugin: registers one pass type through KESTREL_PLUGIN.
#include <kestrel/Kestrel.h>

namespace {

/// out = 42 everywhere: proves the plugin's code really runs in a graph.
class FortyTwoPass : public kestrel::Pass {
public:
    static kestrel::PassDesc describe() {
        return kestrel::PassDesc("PluginFortyTwo", "writes 42")
            .output("out", kestrel::Format::Float, "42");
    }
    explicit FortyTwoPass(const kestrel::ParamValues&) {}
    void execute(kestrel::FrameContext&, kestrel::PassIO& io) override {
        const kestrel::ImageView& o = io.output("out");
        for (size_t i = 0; i < o.pixels(); ++i) o.channel(0)[i] = 42.f;
    }
};

}  // namespace

KESTREL_PLUGIN(r) {
    r.add<FortyTwoPass>();
}
