// Registers a type name the good test plugin already registers: loading both must fail.
#include <kestrel/Kestrel.h>

namespace {

class ImpostorPass : public kestrel::Pass {
public:
    static kestrel::PassDesc describe() {
        return kestrel::PassDesc("PluginFortyTwo", "same name, other module")
            .output("out", kestrel::Format::Float, "nothing");
    }
    explicit ImpostorPass(const kestrel::ParamValues&) {}
    void execute(kestrel::FrameContext&, kestrel::PassIO&) override {}
};

}  // namespace

KESTREL_PLUGIN(r) {
    r.add<ImpostorPass>();
}
