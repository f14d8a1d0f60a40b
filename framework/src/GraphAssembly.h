// What a graph document holds after include and extends (GraphGroups.cpp reads it), which the
// group expansion (GraphExpand.cpp) turns into the flat GraphDesc (docs/graphs.md).
#pragma once

#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "GraphInternal.h"

namespace kestrel::detail {

// Instances of instances multiply: a few nested levels of a few instances each are already
// thousands of passes. A graph past this is a mistake (or a fuzzer), not a pipeline.
constexpr size_t kMaxExpandedPasses = 100000;
constexpr size_t kMaxNesting = 32;

struct PassItem {
    const nlohmann::json* j = nullptr;
    std::string origin;
    std::string name;
};
struct EdgeItem {
    std::string from;
    std::vector<std::string> to;
    bool toArray = false;
    bool history = false;
    std::string origin;
};
struct OutputItem {
    std::string text;
    std::string origin;
};
struct GroupDef {
    const nlohmann::json* j = nullptr;
    std::string origin;  ///< "graphs/lib/svgf-chain.json: groups.svgf-chain"
    std::string file;    ///< the file it is written in (display form)
};
/// A document's contents after include and extends: what the expansion works from.
struct Assembly {
    std::vector<PassItem> passes;
    std::vector<EdgeItem> edges;
    std::vector<OutputItem> outputs;
};

/// Every group the document and its includes define, by name.
using GroupTable = std::map<std::string, GroupDef>;

std::string join(const std::vector<std::string>& v, const char* sep = ", ");
/// "diffuse" of "diffuse.color".
std::string firstComponent(const std::string& s);
std::string listOrNone(const std::vector<std::string>& v);
/// obj[key] as names (without '.'); problems are reported at `keyPath`.
std::vector<std::string> stringList(const nlohmann::json& obj, const char* key,
                                    const std::string& keyPath, std::vector<Diagnostic>& diags);
/// One edge as written; "to" may be an array (one source feeding several inputs).
void parseEdge(const nlohmann::json& je, const std::string& p, std::vector<EdgeItem>& out,
               std::vector<Diagnostic>& diags);

/// Expands `a`'s passes, group instances, edges and outputs into `g` (GraphExpand.cpp).
void expandAssembly(const Assembly& a, const GroupTable& groups, GraphDesc& g,
                    std::vector<Diagnostic>& diags);

}  // namespace kestrel::detail
