#include "SelectPass.h"

using namespace kestrel;

PassDesc SelectPass::describe() {
    PassDesc d("Select",
               "Forwards 'preferred' when it is produced for this scene, else 'fallback' (chosen at"
               " compile time; the unused branch is pruned).");
    d.optionalInput("preferred", Format::Any, "first choice")
        .optionalInput("fallback", Format::Any, "used when 'preferred' has no producer")
        .output("output", Format::Any, "the chosen input");
    return d;
}

void SelectPass::resolve(ResolveContext& rc) {
    if (rc.isBound("preferred")) {
        rc.forward("output", "preferred");
        rc.note("using 'preferred'");
    } else if (rc.isBound("fallback")) {
        rc.forward("output", "fallback");
        rc.note("'preferred' is not produced for this scene: using 'fallback'");
    } else {
        // Name what each branch lacks (a missing channel and how to enable it), once where
        // both lack the same.
        const std::string a = rc.unboundReason("preferred"), b = rc.unboundReason("fallback");
        std::string why = "neither 'preferred' nor 'fallback' is produced for this scene";
        if (a == b && !a.empty())
            why += ": " + a;
        else if (!a.empty() || !b.empty())
            why += ": 'preferred': " + (a.empty() ? "unbound" : a) +
                   "; 'fallback': " + (b.empty() ? "unbound" : b);
        rc.setAbsent("output", why);
    }
}

void SelectPass::execute(FrameContext&, PassIO&) {
    // Never reached: resolve() forwards or marks the output absent.
    throw Error("Select executed: its output should have been forwarded at compile time");
}
