#pragma once
// Internal: JSON helpers shared by the graph parser (Graph.cpp) and the group expansion
// (GraphGroups.cpp).
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "kestrel/Graph.h"

namespace kestrel::detail {

/// Parses JSON text; a syntax error is a GraphError naming `where`, line and column.
nlohmann::json parseJsonText(const std::string& text, const std::string& where);
/// Reads a graph (or group library) file, refusing what cannot be one (a device, 16 MiB+).
std::string readGraphText(const std::filesystem::path& path);
/// One diagnostic per key of `obj` not in `allowed`, at `path`.key.
void checkKeys(const nlohmann::json& obj, const std::set<std::string>& allowed,
               const std::string& path, std::vector<Diagnostic>& diags);
/// The "kestrel" version key of a document (missing or another version is a diagnostic).
void checkVersion(const nlohmann::json& doc, const std::string& prefix,
                  std::vector<Diagnostic>& diags);

/// Builds the flat graph of a parsed document: includes, extends, groups and instances expanded.
/// Structural problems are appended to `diags`.
void expandDocument(const nlohmann::json& doc, const std::filesystem::path& source, GraphDesc& g,
                    std::vector<Diagnostic>& diags);

/// A group parameter's declaration: a bare default, or `{ "default": D, "type": T, "min": A,
/// "max": B, "comment": C }`. Sets `value` to the default and `spec` to its type and range;
/// problems are appended to `diags` at `path`.
void parseGroupParam(const nlohmann::json& decl, const std::string& path, nlohmann::json& value,
                     GroupParamSpec& spec, std::vector<Diagnostic>& diags);
/// "" when `value` fits `spec`, else what was expected ("expected an integer in [1, 5], got 7").
std::string checkGroupValue(const GroupParamSpec& spec, const nlohmann::json& value);

/// The groups `file` itself defines.
std::vector<GroupInfo> groupsOfFile(const std::filesystem::path& file);

}  // namespace kestrel::detail
