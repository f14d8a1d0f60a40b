#pragma once
// Opening an EXR file safely: everything in the header that OpenEXR sizes an allocation by is
// checked BEFORE OpenEXR allocates it -- attribute sizes against the bytes left in the file (a
// 500-byte file can declare a 2 GB attribute), the windows against a pixel limit (or a 100000 x
// 100000 data window), the chunk offset tables against the file size, the chunk buffers against
// the pixel limit -- then the same stream is handed to Imf::InputFile, or, for single-part
// scan-line ZIP/ZIPS files, the offset table to ZipScanlines (InputFile is then opened only if
// that path finds the file damaged).
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>

#include <cstdint>
#include <memory>
#include <string>

#include "Box.h"
#include "ZipScanlines.h"

namespace kestrel::exr {

/// Scan lines per chunk of a compression (OpenEXR's numLinesInBuffer; 1 for unknown ones).
int linesPerChunk(Imf::Compression c);

class ExrInput {
public:
    /// Throws kestrel::Error with a reason (caller adds file and frame): missing, not an EXR,
    /// unsupported (deep), corrupt header (an attribute larger than the file or disagreeing with
    /// its type, more chunks than the file can hold), window larger than maxPixels, a chunk
    /// buffer over 16 bytes x maxPixels.
    ExrInput(const std::string& path, int64_t maxPixels);
    ~ExrInput();

    const std::string& path() const { return path_; }
    const Imf::Header& header() const { return header_; }
    /// OpenEXR's reader, opened on first use when the ZIP fast path is there (its line buffers
    /// are then never allocated unless that path finds the file damaged).
    Imf::InputFile& file();
    /// The fast path for single-part scan-line ZIP/ZIPS files, else nullptr.
    const ZipScanlines* zip() const { return zip_.get(); }
    Box dataWindow() const { return data_; }
    Box displayWindow() const { return display_; }

private:
    void openFile();

    std::string path_;
    std::unique_ptr<Imf::IStream> stream_;
    std::unique_ptr<Imf::InputFile> file_;
    Imf::Header header_;
    std::unique_ptr<ZipScanlines> zip_;
    Box data_, display_;
};

}  // namespace kestrel::exr
