#pragma once
// Shared helpers of the EXR pass tests: writing small EXR files, reading channels back with
// OpenEXR directly, and a ResolveContext that records what a pass declares.
#include <OpenEXR/ImfCompression.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfPixelType.h>

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "kestrel/Pass.h"

namespace exrtest {

namespace fs = std::filesystem;

/// A fresh, empty temporary folder removed at destruction.
struct TempDir {
    fs::path path;
    explicit TempDir(const std::string& name);
    ~TempDir();
};

/// Channel name -> planar values (width*height, row-major over the data window).
using Channels = std::map<std::string, std::vector<float>>;

struct WriteOptions {
    Imf::PixelType type = Imf::FLOAT;
    Imf::Compression compression = Imf::ZIP_COMPRESSION;
    bool tiled = false;
    Imath::Box2i display{{0, 0}, {-1, -1}};  ///< empty: equal to the data window
};

/// Writes `channels` over data window `dw`; `extra` adds attributes (kestrel.layout etc.).
void writeExr(const fs::path& file, const Imath::Box2i& dw, const Channels& channels,
              const WriteOptions& opt = {}, const Imf::Header* extra = nullptr);

/// Reads every channel of a file (for speed comparisons).
void readAllChannels(const fs::path& file);
/// Reads one channel of a file as floats over its data window.
std::vector<float> readChannel(const fs::path& file, const std::string& channel);

class RecordingResolve : public kestrel::ResolveContext {
public:
    explicit RecordingResolve(int64_t first) : first_(first) {}
    bool isBound(std::string_view) const override { return false; }
    void forward(std::string_view, std::string_view) override {}
    void setAbsent(std::string_view output, std::string reason) override {
        absent[std::string(output)] = std::move(reason);
    }
    void note(std::string message) override { notes.push_back(std::move(message)); }
    void setFact(std::string key, std::string value) override { facts[key] = value; }
    std::optional<std::string> fact(std::string_view key) const override {
        auto it = facts.find(std::string(key));
        if (it == facts.end()) return std::nullopt;
        return it->second;
    }
    int64_t firstFrame() const override { return first_; }
    std::string_view passName() const override { return "loader"; }

    std::map<std::string, std::string> absent;
    std::vector<std::string> notes;
    std::map<std::string, std::string> facts;

private:
    int64_t first_;
};

/// The message of the Error resolving `pass` (first frame 1) throws, "" when it throws none.
std::string resolveError(kestrel::Pass& pass);

/// KESTREL_SHARED_DIR/data/<name>, or "" when absent.
std::string sharedData(const std::string& name);

}  // namespace exrtest
