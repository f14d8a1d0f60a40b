#include <kestrel/Compiler.h>
#include <kestrel/Graph.h>
#include <kestrel/Registry.h>

#include <string>

#include "FuzzTargets.h"

namespace kestrel::fuzz {

bool graphTarget(const uint8_t* data, size_t size, const Registry& registry) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    try {
        GraphDesc g = parseGraph(text, "fuzz.json");
        CompileOptions o;
        o.validateOnly = true;
        auto compiled = compileGraph(g, registry, o);
        (void)compiled->toDot();
        (void)compiled->provenanceJson();
        (void)compiled->executionOrder();
        return true;
    } catch (const Error&) {
        return false;  // rejected with a message: the expected outcome for bad input
    }
}

}  // namespace kestrel::fuzz
