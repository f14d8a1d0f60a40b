#pragma once
// The JSON graph description, parsed but not yet compiled.
//
//   { "kestrel": 1, "name": "svgf", "comment": "...",
//     "passes":  [ { "name": "input", "type": "ExrLoader", "params": { ... } }, ... ],
//     "edges":   [ { "from": "input.color", "to": "demod.color" },
//                  { "from": "atrous0.color", "to": "temporal.history", "history": true } ],
//     "outputs": [ "taa.color" ] }
//
// Sinks (writers) are outputs by themselves; "outputs" marks further pass.port results to keep.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "kestrel/Error.h"

namespace kestrel {

constexpr int kGraphFormatVersion = 1;

struct PassNode {
    std::string name;
    std::string type;
    std::string paramsJson = "{}";  ///< the JSON object of parameters, as written
    std::string comment;
};

struct EdgeDesc {
    std::string fromPass, fromPort, toPass, toPort;
    bool history = false;
};

struct GraphDesc {
    std::string name;
    std::string comment;
    std::filesystem::path sourcePath;
    std::vector<PassNode> passes;
    std::vector<EdgeDesc> edges;
    std::vector<std::string> outputs;  ///< "pass.port" or "pass"
};

/// Parses JSON text. Syntax errors report line and column; structural errors (missing keys,
/// wrong types, bad "pass.port" strings, duplicate pass names) are gathered into one GraphError.
GraphDesc parseGraph(const std::string& jsonText, const std::filesystem::path& source = {});
/// Reads and parses a file; an unreadable file is an Error naming it.
GraphDesc loadGraphFile(const std::filesystem::path& path);

/// Applies `pass.param=value` overrides (value parsed as JSON, else taken as a string). `pass`
/// may be a shell pattern (`*atrous*`): every matching pass gets the value. A name or pattern
/// matching no pass is an Error naming the override.
void applyOverride(GraphDesc& graph, const std::string& assignment);

}  // namespace kestrel
