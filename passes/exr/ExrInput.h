#pragma once
// Opening an EXR file safely: everything in the header that OpenEXR sizes an allocation by is
// checked BEFORE OpenEXR allocates it -- attribute sizes against the bytes left in the file (a
// 500-byte file can declare a 2 GB attribute), the windows against a pixel limit (or a 100000 x
// 100000 data window), the chunk offset tables against the file size, the chunk buffers against
// the pixel limit -- then the same stream is handed to Imf::InputFile.
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>

#include <cstdint>
#include <memory>
#include <string>

namespace kestrel::exr {

struct Box {
    int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  // inclusive, as EXR windows
    int64_t width() const { return int64_t(x1) - x0 + 1; }
    int64_t height() const { return int64_t(y1) - y0 + 1; }
    bool operator==(const Box&) const = default;
};

class ExrInput {
public:
    /// Throws kestrel::Error with a reason (caller adds file and frame): missing, not an EXR,
    /// unsupported (deep), corrupt header (an attribute larger than the file or disagreeing with
    /// its type, more chunks than the file can hold), window larger than maxPixels, a chunk
    /// buffer over 16 bytes x maxPixels.
    ExrInput(const std::string& path, int64_t maxPixels);
    ~ExrInput();

    const std::string& path() const { return path_; }
    const Imf::Header& header() const { return file_->header(); }
    Imf::InputFile& file() { return *file_; }
    Box dataWindow() const { return data_; }
    Box displayWindow() const { return display_; }

private:
    std::string path_;
    std::unique_ptr<Imf::IStream> stream_;
    std::unique_ptr<Imf::InputFile> file_;
    Box data_, display_;
};

}  // namespace kestrel::exr
