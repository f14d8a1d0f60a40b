#pragma once
// ZipScanlines: decodes single-part scan-line files with ZIP or ZIPS compression (what Blender
// and `kestrel scenegen` write) straight into the loader's float planes, without OpenEXR's line
// buffers. OpenEXR 3.1's InputFile keeps 2 x threads line buffers, each three chunk-sized
// buffers of every channel of the file (37 MB for a 1080p frame of 25 float channels with two
// threads), and inflates with zlib; this path keeps one chunk per thread and inflates with
// libdeflate (what OpenEXR itself moved to in 3.2). Anything it cannot validate (a damaged
// offset table or chunk, an inflate error) makes decode() return false, and the caller reads
// the file through OpenEXR, which reports the damage in its own words.
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfPixelType.h>

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "Absurd.h"
#include "Box.h"
#include "Workspace.h"

namespace kestrel::exr {

class ZipScanlines {
public:
    /// The file's decoding plan, or nullptr when the file is not single-part scan-line ZIP/ZIPS
    /// with full-resolution HALF, FLOAT or UINT channels. Reads the offset table (`chunks`
    /// entries at `tablePos`; the caller has checked that they fit in the file) from `in`.
    static std::unique_ptr<ZipScanlines> plan(const std::string& path, const Imf::Header& h,
                                              bool singlePartScanlines, Imf::IStream& in,
                                              uint64_t tablePos, uint64_t fileSize);

    /// Decodes `chans` (file channel name, plane of the display window `dp`, W wide) for the
    /// rows the data window and display window share, on up to `threads` threads; channels
    /// the file lacks are filled with their `fill` value. Pixels outside the data window are
    /// not touched. False (with the reason in `why`) if the file's data does not check out.
    struct Stats {
        int chunks = 0;  ///< chunks decoded
        int stored = 0;  ///< of which stored uncompressed (deflate did not shrink them)
    };
    /// `lent`: a decoding thread takes two regions (packed and inflated chunk) where each holds
    /// a chunk, else maps its own buffers. `fixes` (empty, or one per entry of `chans`): the
    /// absurd values of a channel replaced as each row is decoded (Absurd.h).
    bool decode(const Box& dp, int W, const std::vector<std::pair<std::string, float*>>& chans,
                const std::vector<float>& fill, int threads, std::string* why,
                Stats* stats = nullptr, const Workspace& lent = {},
                const std::vector<AbsurdFix>& fixes = {}) const;

    struct Channel {
        std::string name;
        Imf::PixelType type;
        uint64_t lineOffset;  ///< bytes before this channel's values within one scan line
    };

private:
    bool decodeChunk(int fd, int chunk, const std::vector<float*>& dst,
                     const std::vector<AbsurdFix>& fix, const Box& dp, int W,
                     struct ChunkBuffers& buf, bool* stored, std::string* why) const;

    std::string path_;
    Box data_{};
    int linesPerChunk_ = 1;
    bool decreasing_ = false;  // chunks stored bottom first
    uint64_t bytesPerLine_ = 0, tableEnd_ = 0, fileSize_ = 0;
    std::vector<Channel> channels_;
    std::vector<uint64_t> offsets_;
};

}  // namespace kestrel::exr
