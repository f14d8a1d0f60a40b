#include "SelectPass.h"

using namespace kestrel;

SelectPass::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "Select",
          "Forwards 'preferred' when it is produced for this scene, else 'fallback' (chosen at"
          " compile time; the unused branch is pruned).") {
    preferred = optionalInput("preferred", Format::Any, "first choice");
    fallback = optionalInput("fallback", Format::Any, "used when 'preferred' has no producer");
    out = output("output", Format::Any, "the chosen input");
}

const SelectPass::Declaration& SelectPass::declaration() {
    static const Declaration d;
    return d;
}

void SelectPass::resolve(ResolveContext& rc) {
    const Declaration& d = declaration();
    if (rc.isBound(d.preferred)) {
        rc.forward(d.out, d.preferred);
        rc.note("using 'preferred'");
    } else if (rc.isBound(d.fallback)) {
        rc.forward(d.out, d.fallback);
        rc.note("'preferred' is not produced for this scene: using 'fallback'");
    } else {
        // Name what each branch lacks (a missing channel and how to enable it), once where
        // both lack the same.
        const std::string a = rc.unboundReason(d.preferred), b = rc.unboundReason(d.fallback);
        std::string why = "neither 'preferred' nor 'fallback' is produced for this scene";
        if (a == b && !a.empty())
            why += ": " + a;
        else if (!a.empty() || !b.empty())
            why += ": 'preferred': " + (a.empty() ? "unbound" : a) +
                   "; 'fallback': " + (b.empty() ? "unbound" : b);
        rc.setAbsent(d.out, why);
    }
}

void SelectPass::execute(FrameContext&, PassIO&) {
    // Never reached: resolve() forwards or marks the output absent.
    throw Error("Select executed: its output should have been forwarded at compile time");
}
