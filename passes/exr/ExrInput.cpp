#include "ExrInput.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/ImfTileDescription.h>
#include <OpenEXR/ImfVersion.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string_view>
#include <vector>

#include "NotExr.h"
#include "kestrel/Error.h"

namespace kestrel::exr {

/// Scan lines per chunk of each compression (OpenEXR's numLinesInBuffer).
int linesPerChunk(Imf::Compression c) {
    switch (c) {
        case Imf::ZIP_COMPRESSION:
        case Imf::PXR24_COMPRESSION:
            return 16;
        case Imf::PIZ_COMPRESSION:
        case Imf::B44_COMPRESSION:
        case Imf::B44A_COMPRESSION:
        case Imf::DWAA_COMPRESSION:
            return 32;
        case Imf::DWAB_COMPRESSION:
            return 256;
        default:
            return 1;  // none, RLE, ZIPS (and unknown: the most chunks)
    }
}

namespace {
Box toBox(const Imath::Box2i& b) {
    return {b.min.x, b.min.y, b.max.x, b.max.y};
}

void checkWindow(const char* what, const Box& b, int64_t maxPixels) {
    if (b.width() <= 0 || b.height() <= 0) throw Error(std::string("empty or inverted ") + what);
    // Coordinates are ints: a window spanning more than INT_MAX pixels would overflow the
    // decoders' int offsets (found in review; only a maxPixels above 2^31 lets one through).
    if (b.width() > std::numeric_limits<int>::max() || b.height() > std::numeric_limits<int>::max())
        throw Error(std::string(what) + " " + std::to_string(b.width()) + "x" +
                    std::to_string(b.height()) + " spans more than 2^31 - 1 pixels");
    // Each factor fits in 33 bits but their product may not fit in int64 (found by exr_fuzzer):
    // compare by division (height > 0 here).
    if (b.width() > maxPixels / b.height())
        throw Error(std::string(what) + " " + std::to_string(b.width()) + "x" +
                    std::to_string(b.height()) + " exceeds maxPixels " + std::to_string(maxPixels) +
                    " (refused before allocating)");
}

/// OpenImageIO's rule for a header not to trust: the pixels it declares (the data window's
/// pixels times each channel's stored size) over 10,000 times the file's size and over 1 GiB.
/// Real EXRs compress far less; a 4 MB file declaring 4000x4000 made a run allocate 4.3 GB.
void checkDeclaredSize(const Imf::Header& h, const Box& dw, uint64_t fileSize) {
    uint64_t bytesPerPixel = 0, channels = 0;
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it, ++channels)
        bytesPerPixel += it.channel().type == Imf::HALF ? 2 : 4;  // UINT and FLOAT: 4
    const uint64_t declared = uint64_t(dw.width()) * uint64_t(dw.height()) * bytesPerPixel;
    constexpr uint64_t kRatio = 10000, kFloor = uint64_t(1) << 30;
    if (declared > kFloor && declared / kRatio > fileSize)
        throw Error("data window " + std::to_string(dw.width()) + "x" +
                    std::to_string(dw.height()) + " with " + std::to_string(channels) +
                    " channels declares " + std::to_string(declared) +
                    " bytes of pixels, over 10,000 times the file's " + std::to_string(fileSize) +
                    " bytes and over 1 GiB (OpenImageIO's limit): a damaged or forged header "
                    "(refused before allocating)");
}

/// Value size of the fixed-size attribute types OpenEXR 3.1 knows, else -1. Their readers read
/// exactly this many bytes whatever size the file declares, so a different declared size would
/// make the walk below and OpenEXR's own parse see different attributes.
int fixedValueSize(std::string_view type) {
    // clang-format off
    static const std::pair<std::string_view, int> sizes[] = {
        {"box2i", 16}, {"box2f", 16}, {"chromaticities", 32}, {"compression", 1},
        {"deepImageState", 1}, {"double", 8}, {"envmap", 1}, {"float", 4}, {"int", 4},
        {"keycode", 28}, {"lineOrder", 1}, {"m33f", 36}, {"m33d", 72}, {"m44f", 64},
        {"m44d", 128}, {"rational", 8}, {"tiledesc", 9}, {"timecode", 8}, {"v2i", 8},
        {"v2f", 8}, {"v2d", 16}, {"v3i", 12}, {"v3f", 12}, {"v3d", 24}};
    // clang-format on
    for (const auto& [name, size] : sizes)
        if (type == name) return size;
    return -1;
}

/// Walks the attribute list(s) of a header without allocating anything the file sizes.
///
/// Imf::Header::readFrom allocates each attribute value at its declared size before reading it
/// (new char[size] for an unknown type, a zero-filled std::string for a string): a 500-byte file
/// declaring a 2 GB attribute makes it allocate -- and for strings touch -- 2 GB before the read
/// fails at the end of the file. So every declared size is checked against the bytes the file has
/// left first, and the walk keeps in step with OpenEXR's parse (fixed-size types must declare
/// their size, channel and string lists must fill theirs exactly) so that what it checked is what
/// OpenEXR then reads.
class HeaderWalk {
public:
    HeaderWalk(Imf::IStream& s, uint64_t fileSize) : s_(s), end_(fileSize), pos_(s.tellg()) {}

    uint64_t pos() const { return pos_; }
    uint64_t left() const { return end_ > pos_ ? end_ - pos_ : 0; }

    /// One header's attributes; false if it has none (the empty header ending a multi-part
    /// file's list).
    bool header() {
        for (int count = 0;; ++count) {
            std::string name = readName("attribute name");
            if (name.empty()) return count > 0;
            std::string type = readName("type name of attribute '" + name + "'");
            const int32_t size = readInt();
            if (size < 0 || uint64_t(size) > left())
                throw Error("attribute '" + name + "' (" + type + ") declares a " +
                            std::to_string(size) + "-byte value but the file has " +
                            std::to_string(left()) + " bytes left (refused before allocating)");
            value(name, type, uint32_t(size));
        }
    }

private:
    void value(const std::string& name, const std::string& type, uint32_t size) {
        const uint64_t end = pos_ + size;
        auto mismatch = [&](const std::string& what) {
            return Error("attribute '" + name + "' (" + type + "): " + what +
                         " does not match its declared size " + std::to_string(size));
        };
        if (const int fixed = fixedValueSize(type); fixed >= 0) {
            if (size != uint32_t(fixed)) throw mismatch("its type's " + std::to_string(fixed));
            skip(size);
        } else if (type == "chlist") {  // names, each followed by 16 bytes; an empty name ends it
            for (;;) {
                if (pos_ >= end) throw mismatch("the channel list");
                if (readName("channel name").empty()) break;
                skip(16);
            }
            if (pos_ != end) throw mismatch("the channel list");
        } else if (type == "stringvector") {  // (length, bytes) pairs
            while (pos_ < end) {
                const int32_t n = readInt();
                if (n < 0 || pos_ + uint64_t(n) > end) throw mismatch("a string length");
                skip(uint32_t(n));
            }
            if (pos_ != end) throw mismatch("the string list");
        } else if (type == "preview") {  // width, height, then 4 bytes per pixel
            if (size < 8) throw mismatch("the preview's 8-byte dimensions");
            const int32_t w = readInt(), h = readInt();
            if (w < 0 || h < 0 || uint64_t(w) * uint64_t(h) * 4 + 8 != size)
                throw mismatch("a " + std::to_string(w) + "x" + std::to_string(h) + " preview");
            skip(size - 8);
        } else if (type == "floatvector" && size % 4 != 0) {
            throw mismatch("a whole number of floats");
        } else {  // string, opaque (unknown type) and the rest: read as `size` bytes
            skip(size);
        }
    }

    void read(char* p, uint64_t n) {
        if (n > left()) throw Error("header runs past the end of the file");
        s_.read(p, int(n));
        pos_ += n;
    }
    void skip(uint64_t n) {
        if (n > left()) throw Error("header runs past the end of the file");
        pos_ += n;
        s_.seekg(pos_);
    }
    int32_t readInt() {
        unsigned char b[4];
        read(reinterpret_cast<char*>(b), 4);
        return int32_t(uint32_t(b[0]) | uint32_t(b[1]) << 8 | uint32_t(b[2]) << 16 |
                       uint32_t(b[3]) << 24);
    }
    /// A NUL-terminated name of at most Imf::Name::MAX_LENGTH (255) characters, as OpenEXR reads.
    std::string readName(const std::string& what) {
        std::string s;
        for (char c; read(&c, 1), c != 0;) {
            if (s.size() == 255) throw Error(what + " is longer than 255 characters");
            s += c;
        }
        return s;
    }

    Imf::IStream& s_;
    uint64_t end_, pos_;
};

/// Chunk buffers may hold up to this many bytes per maxPixels pixel (RGBA float).
constexpr uint64_t kMaxBytesPerPixel = 16;
constexpr uint64_t kManyChunks = uint64_t(1) << 60;  // saturation: far above any file

uint64_t addChunks(uint64_t a, uint64_t b) {
    return b > kManyChunks - std::min(a, kManyChunks) ? kManyChunks : a + b;
}

/// Chunks of one part (scan-line blocks, or tiles over all levels): the entries of the offset
/// table OpenEXR allocates and fills before reading any pixel. Robust to values sanityCheck
/// would refuse (other parts of a multi-part file are not sanity-checked here).
uint64_t chunkCount(const Imf::Header& h, bool tiled) {
    const Box dw = toBox(h.dataWindow());
    if (dw.width() <= 0 || dw.height() <= 0) return 0;
    const uint64_t w = uint64_t(dw.width()), ht = uint64_t(dw.height());
    if (!tiled || !h.hasTileDescription()) {
        const uint64_t lines = uint64_t(linesPerChunk(h.compression()));
        return (ht + lines - 1) / lines;
    }
    const Imf::TileDescription& t = h.tileDescription();
    const uint64_t tx = std::max(1u, t.xSize), ty = std::max(1u, t.ySize);
    const bool up = t.roundingMode == Imf::ROUND_UP;
    auto levels = [&](uint64_t size) {  // log2 rounded as the mode says, plus one
        int n = 0;
        while ((uint64_t(1) << (n + 1)) <= size) ++n;  // floor(log2(size))
        if (up && (uint64_t(1) << n) < size) ++n;
        return n + 1;
    };
    auto levelSize = [&](uint64_t size, int l) {
        return std::max<uint64_t>(1, up ? (size + (uint64_t(1) << l) - 1) >> l : size >> l);
    };
    auto tiles = [&](int lx, int ly) {  // each factor < 2^32: the product fits
        return ((levelSize(w, lx) + tx - 1) / tx) * ((levelSize(ht, ly) + ty - 1) / ty);
    };
    uint64_t n = 0;
    if (t.mode == Imf::ONE_LEVEL) {
        n = tiles(0, 0);
    } else if (t.mode == Imf::MIPMAP_LEVELS) {
        for (int l = 0; l < levels(std::max(w, ht)); ++l) n = addChunks(n, tiles(l, l));
    } else {  // RIPMAP_LEVELS (and unknown modes: the most tiles)
        for (int ly = 0; ly < levels(ht); ++ly)
            for (int lx = 0; lx < levels(w); ++lx) n = addChunks(n, tiles(lx, ly));
    }
    return n;
}

/// Decoded bytes of the largest buffer OpenEXR sizes by the chunk shape, all channels: a block
/// of `lines per chunk` scan lines of the data window, or for tiled files a tile, or a row of
/// tiles (data window width x tile height: Imf::InputFile caches one to serve scan lines). They
/// are allocated when the file is opened or the frame buffer set, whatever the window's height,
/// so a 4-row image can declare 50331652x4 tiles. Every channel counts 4 bytes a pixel, half or
/// subsampled ones too (an upper bound; the loader reads all as float, and the row cache holds
/// the frame buffer's type). Saturates instead of overflowing.
uint64_t chunkBytes(const Imf::Header& h, bool tiled, std::string* shape) {
    uint64_t bytesPerPixel = 0;
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it) bytesPerPixel += 4;
    const uint64_t width = uint64_t(std::max<int64_t>(0, toBox(h.dataWindow()).width()));
    uint64_t w, rows;
    if (tiled && h.hasTileDescription()) {
        const uint64_t tx = h.tileDescription().xSize, ty = h.tileDescription().ySize;
        w = std::max(tx, width);
        rows = ty;
        *shape = "tile " + std::to_string(tx) + "x" + std::to_string(ty);
        if (width > tx) *shape += " in rows of " + std::to_string(width) + "x" + std::to_string(ty);
    } else {
        w = width;
        rows = uint64_t(linesPerChunk(h.compression()));
        *shape = "block of " + std::to_string(rows) + " scan lines " + std::to_string(w) + " wide";
    }
    *shape += ", " + std::to_string(bytesPerPixel) + " bytes per pixel";
    const uint64_t pixels = w * rows;  // both < 2^32
    if (bytesPerPixel && pixels > kManyChunks / bytesPerPixel) return kManyChunks;
    return pixels * bytesPerPixel;
}
}  // namespace

ExrInput::ExrInput(const std::string& path, int64_t maxPixels) : path_(path) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) throw Error("file not found");
    const uint64_t fileSize = std::filesystem::file_size(path, ec);
    if (ec) throw Error("cannot read the file size: " + ec.message());
    try {
        stream_ = std::make_unique<Imf::StdIFStream>(path.c_str());
        char magic[4] = {};
        stream_->read(magic, 4);
        if (!Imf::isImfMagic(magic)) {  // PNG, HDR, TIFF frames: named, with what is needed
            unsigned char head[8] = {};
            std::ifstream(path, std::ios::binary).read(reinterpret_cast<char*>(head), 8);
            throw Error(notExrMessage(head, std::min<uint64_t>(fileSize, 8)));
        }
        unsigned char v[4] = {};
        stream_->read(reinterpret_cast<char*>(v), 4);
        int version = int(v[0] | (v[1] << 8) | (v[2] << 16) | (unsigned(v[3]) << 24));
        if (Imf::getVersion(version) != Imf::EXR_VERSION ||
            !Imf::supportsFlags(Imf::getFlags(version)))
            throw Error("unsupported OpenEXR version field");
        if (Imf::isNonImage(version)) throw Error("deep images are not supported");
        const bool multiPart = Imf::isMultiPart(version);

        // Attribute sizes first (nothing allocated), then the headers themselves: attributes
        // only, no pixel or offset-table allocation yet.
        const uint64_t headersStart = stream_->tellg();
        HeaderWalk walk(*stream_, fileSize);
        size_t partCount = 1;
        if (multiPart) {  // headers up to an empty one
            for (partCount = 0; walk.header();) ++partCount;
            if (partCount == 0) throw Error("multi-part file with no part");
        } else {
            walk.header();
        }
        const uint64_t headersEnd = walk.pos();
        stream_->seekg(headersStart);
        std::vector<Imf::Header> parts(partCount);
        for (Imf::Header& h : parts) h.readFrom(*stream_, version);
        const Imf::Header& probe = parts[0];
        data_ = toBox(probe.dataWindow());
        display_ = toBox(probe.displayWindow());
        checkWindow("data window", data_, maxPixels);
        checkWindow("display window", display_, maxPixels);
        probe.sanityCheck(Imf::isTiled(version), multiPart);

        // OpenEXR allocates every part's chunk offset table (8 bytes an entry) when the file
        // is opened: the declared chunks must at least fit in what follows the headers.
        auto tiled = [&](const Imf::Header& h) {
            return multiPart ? h.hasType() && Imf::isTiled(h.type()) : Imf::isTiled(version);
        };
        uint64_t chunks = 0;
        for (const Imf::Header& h : parts) {
            uint64_t n = chunkCount(h, tiled(h));
            if (h.hasChunkCount()) {
                if (h.chunkCount() < 0) throw Error("negative chunkCount attribute");
                n = std::max(n, uint64_t(h.chunkCount()));
            }
            chunks = addChunks(chunks, n);
        }
        const uint64_t after = fileSize - std::min(fileSize, headersEnd);
        if (chunks > after / 8)
            throw Error("header declares " + std::to_string(chunks) + " chunks (" +
                        (multiPart ? std::to_string(parts.size()) + " parts"
                                   : "data window " + std::to_string(data_.width()) + "x" +
                                         std::to_string(data_.height())) +
                        "), whose offset table alone needs " + std::to_string(chunks * 8) +
                        " bytes, but only " + std::to_string(after) +
                        " bytes follow the header (refused before allocating)");

        // The chunk buffers OpenEXR allocates for the part read: at most what a maxPixels
        // image of 4 float channels would take (a real chunk is a strip or a tile of the image).
        std::string shape;
        const uint64_t bytes = chunkBytes(probe, tiled(probe), &shape);
        if (bytes > uint64_t(maxPixels) * kMaxBytesPerPixel)
            throw Error("chunk buffer (" + shape + ") needs " + std::to_string(bytes) +
                        " bytes, more than " + std::to_string(kMaxBytesPerPixel) +
                        " bytes x maxPixels " + std::to_string(maxPixels) + " = " +
                        std::to_string(uint64_t(maxPixels) * kMaxBytesPerPixel) +
                        " (refused before allocating)");
        // After the checks above, whose messages say more about the damage they find.
        checkDeclaredSize(probe, data_, fileSize);

        header_ = probe;
        zip_ = ZipScanlines::plan(path, probe, !multiPart && !tiled(probe), *stream_, headersEnd,
                                  fileSize);
        if (!zip_) openFile();
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        throw Error(std::string("corrupt or unreadable OpenEXR header: ") + e.what());
    }
}

void ExrInput::openFile() {
    stream_->seekg(0);
    file_ = std::make_unique<Imf::InputFile>(*stream_, Imf::globalThreadCount());
}

Imf::InputFile& ExrInput::file() {
    if (!file_) {
        try {
            openFile();
        } catch (const std::exception& e) {
            throw Error(std::string("corrupt or unreadable OpenEXR header: ") + e.what());
        }
    }
    return *file_;
}

ExrInput::~ExrInput() = default;

}  // namespace kestrel::exr
