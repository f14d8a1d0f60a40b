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

/// The groups `file` itself defines.
std::vector<GroupInfo> groupsOfFile(const std::filesystem::path& file);

}  // namespace kestrel::detail
