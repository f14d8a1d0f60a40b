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
//
// Groups (docs/graphs.md): "groups" defines named subgraphs with inputs, outputs and parameters,
// "include" reads group definitions from other files, "extends" starts from another graph
// ("drop" removes passes of it), and a pass with "group" instead of "type" is an instance. They
// are expanded when the file is parsed: a GraphDesc is always flat, its passes named by instance
// path ("diffuse.atrous2"), so the compiler, reports and provenance see plain passes.
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "kestrel/Error.h"

namespace kestrel {

constexpr int kGraphFormatVersion = 1;

class Registry;

struct PassNode {
    std::string name;
    std::string type;
    std::string paramsJson = "{}";  ///< the JSON object of parameters, as written
    std::string comment;
    /// Where the pass is written: "passes[3]" in the graph file, or for a pass expanded from a
    /// group "lib/svgf-chain.json: groups.svgf-chain.passes[9]". Empty: built in code.
    std::string origin = {};
    /// Path of the innermost group instance the pass comes from ("diffuse"), else empty.
    std::string instance = {};
    /// Parameters set from a group parameter: param -> "diffuse.sigmaL" (for error messages).
    std::map<std::string, std::string> boundParams = {};
    /// Parameters set on the command line: param -> the option as typed ("--set
    /// diffuse.iterations=3"). A problem with such a value is the option's, not the file's.
    std::map<std::string, std::string> setBy = {};
};

struct EdgeDesc {
    std::string fromPass, fromPort, toPass, toPort;
    bool history = false;
    std::string origin = {};  ///< JSON path of the edge as written (see PassNode::origin)
};

/// A group parameter's declared type and range (docs/graphs.md): `"iterations": { "default": 5,
/// "min": 1, "max": 5 }`. A parameter written as a bare default takes its default's type.
struct GroupParamSpec {
    std::string type;  ///< "int", "number", "bool", "string" or "" (any JSON value)
    bool hasRange = false;
    double min = 0, max = 0;
};

/// One expanded group instance (nested instances have dotted paths: "outer.inner").
struct GroupInstance {
    std::string path;   ///< "diffuse"
    std::string group;  ///< the definition's name, "svgf-chain"
    std::string origin;
    /// Group parameter -> the (flat pass, parameter) pairs it drives, for --set diffuse.sigmaL=6.
    std::map<std::string, std::vector<std::pair<std::string, std::string>>> bindings;
    /// Group parameter -> its type and range, to check values an override gives it.
    std::map<std::string, GroupParamSpec> specs = {};
};

/// A group definition as written, for listings (`kestrel passes`).
struct GroupInfo {
    std::string name;
    std::string file;
    std::string comment;
    std::vector<std::string> inputs, outputs;
    std::vector<std::pair<std::string, std::string>> params;  ///< name, default as JSON
    size_t passCount = 0;
};

struct GraphDesc {
    std::string name;
    std::string comment;
    std::filesystem::path sourcePath;
    std::vector<PassNode> passes;
    std::vector<EdgeDesc> edges;
    std::vector<std::string> outputs;      ///< "pass.port" or "pass"
    std::vector<GroupInstance> instances;  ///< in expansion order (outer before inner)
    /// The graph file and every file it includes or extends: what no output may replace.
    std::vector<std::filesystem::path> files = {};
};

/// Parses JSON text. Syntax errors report line and column; structural errors (missing keys,
/// wrong types, bad "pass.port" strings, duplicate pass names) are gathered into one GraphError.
GraphDesc parseGraph(const std::string& jsonText, const std::filesystem::path& source = {});
/// Reads and parses a file; an unreadable file is an Error naming it.
GraphDesc loadGraphFile(const std::filesystem::path& path);

/// The group definitions a file declares itself (not those it includes), checked as an include
/// would check them. For `kestrel passes`.
std::vector<GroupInfo> listGroups(const std::filesystem::path& file);

/// Splits "pass.port" at its last dot (pass names of group instances contain dots).
bool splitPassPort(const std::string& s, std::string& pass, std::string& port);

/// Applies `pass.param=value` overrides (value parsed as JSON, else taken as a string). `pass`
/// may be a shell pattern (`*atrous*`): every matching pass gets the value. `pass` may also name
/// a group instance and `param` one of its group parameters (`diffuse.sigmaL=6`): every inner
/// parameter bound to it gets the value. A pattern matching instances with that group parameter
/// (`*.sigmaL`) sets the group parameter only. A name or pattern matching nothing is an Error
/// naming the override.
///
/// With the registry, a misspelt name or parameter is one Error with a suggestion (the case
/// typo `diffuse.sigmal` -> `diffuse.sigmaL`), and a pattern sets a pass parameter only on the
/// matching passes whose type declares it (`'*.sigmaLL=6'` is one error, not one per pass). A
/// value a group parameter's type or range refuses is an Error. `option` is the option the user
/// typed (`--set`, `--sweep`): messages name it, and every parameter set records it
/// (PassNode::setBy) so the compiler blames the option, not the graph file.
/// Returns the (pass, parameter) pairs set.
std::vector<std::pair<std::string, std::string>> applyOverride(GraphDesc& graph,
                                                               const std::string& assignment,
                                                               const Registry* registry = nullptr,
                                                               const std::string& option = "--set");

}  // namespace kestrel
