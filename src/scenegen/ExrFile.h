#pragma once
// Writes one single-part scanline FLOAT EXR (ZIP, row 0 = top) atomically: a temporary file in
// the same folder, then a rename.
#include <filesystem>
#include <string>
#include <vector>

#include "scenegen/SceneGen.h"

namespace kestrel::scenegen {

struct ExrChannel {
    std::string name;
    const float* data;  // width * height floats, row 0 = top
};
struct ExrMatrixAttribute {
    std::string name;
    Mat4 m;  // stored so that M44f x[r][c] == m.m[r][c]
};
struct ExrAttributes {
    std::vector<std::pair<std::string, std::string>> strings;
    std::vector<std::pair<std::string, int>> ints;
    std::vector<ExrMatrixAttribute> matrices;
};

void writeExr(const std::filesystem::path& path, int width, int height,
              const std::vector<ExrChannel>& channels, const ExrAttributes& attributes = {});

/// Writes `bytes` to `path` atomically (temporary file + rename).
void writeFileAtomic(const std::filesystem::path& path, const std::vector<char>& bytes);

}  // namespace kestrel::scenegen
