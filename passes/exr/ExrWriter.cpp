#include "ExrWriter.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStdIO.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/ImfVersion.h>
#include <fcntl.h>
#include <libdeflate.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <tuple>
#include <utility>

#include "ExrInput.h"
#include "ZipWriter.h"

namespace kestrel::exr {

namespace fs = std::filesystem;

namespace {

/// ITU-R BT.709 primaries and the D65 white point (CIE xy), as the chromaticities attribute.
const Imf::Chromaticities kRec709({0.64f, 0.33f}, {0.30f, 0.60f}, {0.15f, 0.06f},
                                  {0.3127f, 0.3290f});
const std::vector<std::string> kCompressions = {"none",  "rle", "zips", "zip",  "piz",
                                                "pxr24", "b44", "b44a", "dwaa", "dwab"};
Imf::Compression compressionOf(const std::string& s) {
    static const Imf::Compression values[] = {
        Imf::NO_COMPRESSION,   Imf::RLE_COMPRESSION,   Imf::ZIPS_COMPRESSION, Imf::ZIP_COMPRESSION,
        Imf::PIZ_COMPRESSION,  Imf::PXR24_COMPRESSION, Imf::B44_COMPRESSION,  Imf::B44A_COMPRESSION,
        Imf::DWAA_COMPRESSION, Imf::DWAB_COMPRESSION};
    for (size_t i = 0; i < kCompressions.size(); ++i)
        if (kCompressions[i] == s) return values[i];
    return Imf::ZIP_COMPRESSION;
}

constexpr float kHalfMax = 65504.f;

fs::path folderOf(const std::string& file) {
    fs::path dir = fs::path(file).parent_path();
    return dir.empty() ? fs::path(".") : dir;
}

/// A temporary name in the destination's folder (rename is atomic only within a file system).
std::string tempName(const std::string& final) {
    fs::path p(final);
    return (folderOf(final) / ("." + p.filename().string() + ".tmp-" + std::to_string(::getpid())))
        .string();
}

/// Flushes `path` (a file or a folder) to the disk. Without it a power loss after the rename
/// can leave the frame's name pointing at an empty or partial file, which --resume would trust.
void syncToDisk(const std::string& path, bool folder) {
    const int fd = ::open(path.c_str(), O_RDONLY | (folder ? O_DIRECTORY : 0) | O_CLOEXEC);
    if (fd < 0) throw Error("cannot open " + path + " to flush it: " + std::strerror(errno));
    const int rc = ::fsync(fd);
    const int err = errno;
    ::close(fd);
    // Some file systems cannot flush a folder (EINVAL): the file itself is on disk already.
    if (rc != 0 && !(folder && err == EINVAL))
        throw Error("cannot flush " + path + " to disk: " + std::strerror(err));
}

uint64_t readLE(const unsigned char* b, int bytes) {
    uint64_t v = 0;
    for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | b[i];
    return v;
}

/// Whether every chunk of a single-part scan-line file lies wholly inside the file: its offset
/// table entry is set, and the chunk's header and data end before the file does. A frame cut
/// short by a crash fails this even when its offset table was written (the writer writes the
/// table last, but other writers do not).
bool chunksPresent(std::ifstream& f, Imf::StdIFStream& is, const Imf::Header& h, uint64_t size) {
    const int lines = linesPerChunk(h.compression());
    const Imath::Box2i dw = h.dataWindow();
    if (dw.max.y < dw.min.y) return false;
    const uint64_t chunks = (uint64_t(dw.max.y - dw.min.y) + uint64_t(lines)) / uint64_t(lines);
    const uint64_t table = is.tellg();
    if (table + chunks * 8 > size) return false;
    std::vector<unsigned char> offsets(chunks * 8);
    f.seekg(std::streamoff(table));
    if (!f.read(reinterpret_cast<char*>(offsets.data()), std::streamsize(offsets.size())))
        return false;
    for (uint64_t i = 0; i < chunks; ++i) {
        const uint64_t at = readLE(&offsets[i * 8], 8);
        unsigned char head[8];
        if (at < table + chunks * 8 || at + 8 > size) return false;
        f.seekg(std::streamoff(at));
        if (!f.read(reinterpret_cast<char*>(head), 8)) return false;
        const uint64_t bytes = readLE(head + 4, 4);
        if (bytes == 0 || bytes > 0x7fffffffu || at + 8 + bytes > size) return false;
    }
    return true;
}

/// The header attribute holding the CRC-32 of everything after the header (the offset table
/// and every chunk) as 8 hex digits. A bit flipped inside a chunk leaves every chunk's size
/// right, and an uncompressed or stored chunk still decodes: only a checksum shows it.
constexpr char kCrcAttribute[] = "kestrel.dataCrc32";
constexpr char kCrcPlaceholder[] = "00000000";

/// A file descriptor closed when it goes out of scope.
struct Fd {
    int fd;
    ~Fd() {
        if (fd >= 0) ::close(fd);
    }
};

/// CRC-32 of the bytes of `fd` from `from` to `to`, read a megabyte at a time.
uint32_t crcOfRange(int fd, uint64_t from, uint64_t to) {
    std::vector<unsigned char> buf(std::min<uint64_t>(to - from, 1u << 20));
    uint32_t crc = 0;
    for (uint64_t at = from; at < to;) {
        const ssize_t got =
            ::pread(fd, buf.data(), size_t(std::min<uint64_t>(buf.size(), to - at)), off_t(at));
        if (got <= 0) throw Error(std::string("cannot read back: ") + std::strerror(errno));
        crc = libdeflate_crc32(crc, buf.data(), size_t(got));
        at += uint64_t(got);
    }
    return crc;
}

std::string hex8(uint32_t v) {
    char text[9];
    std::snprintf(text, sizeof text, "%08x", v);
    return text;
}

/// Fills the placeholder of kCrcAttribute in the (closed) file `path`, whose header ends at
/// `headerEnd`, with the CRC of everything after the header. In place, the header's size and
/// every offset unchanged.
void stampChecksum(const std::string& path, uint64_t headerEnd) {
    const Fd file{::open(path.c_str(), O_RDWR | O_CLOEXEC)};
    const int fd = file.fd;
    if (fd < 0) throw Error(std::string("cannot open to checksum: ") + std::strerror(errno));
    const off_t size = ::lseek(fd, 0, SEEK_END);
    if (size < 0 || uint64_t(size) < headerEnd) throw Error("file shorter than its header");
    const std::string crc = hex8(crcOfRange(fd, headerEnd, uint64_t(size)));
    std::string head(headerEnd, '\0');
    if (::pread(fd, head.data(), head.size(), 0) != ssize_t(head.size()))
        throw Error(std::string("cannot read back the header: ") + std::strerror(errno));
    // name, type name, 4-byte little-endian size (8), value: OpenEXR's attribute layout.
    const std::string key = std::string(kCrcAttribute) + '\0' + "string" + '\0' +
                            std::string("\x08\0\0\0", 4) + kCrcPlaceholder;
    const auto at = head.find(key);
    if (at == std::string::npos) throw Error("no checksum placeholder in the header");
    const off_t valueAt = off_t(at + key.size() - 8);
    if (::pwrite(fd, crc.data(), 8, valueAt) != 8)
        throw Error(std::string("cannot write the checksum: ") + std::strerror(errno));
}

/// Where the header of a single-part scan-line file ends (its offset table starts).
uint64_t headerEndOf(const std::string& path) {
    Imf::Header h;
    std::ifstream f(path, std::ios::binary);
    Imf::StdIFStream is(f, path.c_str());
    unsigned char magic[8];
    if (!f.read(reinterpret_cast<char*>(magic), 8)) throw Error("cannot read the header");
    int version = int(readLE(magic + 4, 4));
    h.readFrom(is, version);
    return is.tellg();
}

/// Reads every pixel of `path` through OpenEXR, which throws on a chunk that does not decode:
/// the check for files without kestrel.dataCrc32 (older or from another writer).
void decodeAll(const std::string& path) {
    Imf::InputFile in(path.c_str(), 1);
    const Imath::Box2i dw = in.header().dataWindow();
    const size_t W = size_t(dw.max.x - dw.min.x + 1), H = size_t(dw.max.y - dw.min.y + 1);
    std::vector<float> plane(W * H);
    for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it) {
        Imf::FrameBuffer fb;  // one channel at a time: one plane of memory
        fb.insert(it.name(),
                  Imf::Slice::Make(Imf::FLOAT, plane.data(), dw, sizeof(float), W * sizeof(float)));
        in.setFrameBuffer(fb);
        in.readPixels(dw.min.y, dw.max.y);
    }
}

/// Why the file cannot be trusted as this run's output (empty: it can). Checked in order of
/// cost: magic and header; the run's provenance (`provenance` empty: not compared); every
/// chunk inside the file; the checksum of the offset table and chunks, or, for a file without
/// one, every chunk decoded. Tiled, multi-part and deep files (not what this writer makes) are
/// trusted when OpenEXR finds all their pixels.
std::string exrProblem(const std::string& path, const std::string& provenance) {
    const std::string broken = "is incomplete, corrupt or unreadable";
    try {
        std::ifstream f(path, std::ios::binary | std::ios::ate);
        if (!f) return broken;
        const uint64_t size = uint64_t(f.tellg());
        f.seekg(0);
        unsigned char magic[8];
        if (size < 8 || !f.read(reinterpret_cast<char*>(magic), 8)) return broken;
        const int version = int(readLE(magic + 4, 4));
        if (int(readLE(magic, 4)) != Imf::MAGIC) return broken;
        if (Imf::isTiled(version) || Imf::isMultiPart(version) || Imf::isNonImage(version)) {
            f.close();
            Imf::InputFile in(path.c_str(), 1);
            return in.isComplete() ? "" : broken;
        }
        Imf::StdIFStream is(f, path.c_str());
        Imf::Header h;
        int v = version;
        h.readFrom(is, v);
        const uint64_t table = is.tellg();
        if (!provenance.empty()) {
            const auto* p = h.findTypedAttribute<Imf::StringAttribute>("kestrel.provenance");
            if (!p || p->value() != provenance)
                return "was written by another graph or other parameters (its "
                       "kestrel.provenance is not this run's)";
        }
        if (!chunksPresent(f, is, h, size)) return broken;
        f.close();
        const auto* crc = h.findTypedAttribute<Imf::StringAttribute>(kCrcAttribute);
        if (!crc) {
            decodeAll(path);  // throws on a chunk that does not decode
            return "";
        }
        const Fd file{::open(path.c_str(), O_RDONLY | O_CLOEXEC)};
        if (file.fd < 0) return broken;
        if (hex8(crcOfRange(file.fd, table, size)) != crc->value())
            return "is corrupt (its data does not match its checksum)";
        return "";
    } catch (const std::exception&) {
        return broken;  // a header or chunk OpenEXR cannot parse: rewrite the frame
    }
}

/// A PNG with its signature first and its closing IEND chunk last: what a write cut short,
/// or one that failed and was never renamed into place, lacks.
bool isCompletePng(const std::string& path) {
    static const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    static const unsigned char iend[12] = {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xae, 0x42, 0x60, 0x82};
    std::ifstream f(path, std::ios::binary | std::ios::ate);
    if (!f) return false;
    const std::streamoff size = f.tellg();
    unsigned char head[8], tail[12];
    if (size < std::streamoff(sizeof head + sizeof tail)) return false;
    f.seekg(0);
    if (!f.read(reinterpret_cast<char*>(head), sizeof head)) return false;
    f.seekg(size - std::streamoff(sizeof tail));
    if (!f.read(reinterpret_cast<char*>(tail), sizeof tail)) return false;
    return std::memcmp(head, signature, sizeof head) == 0 &&
           std::memcmp(tail, iend, sizeof tail) == 0;
}

/// The test-only fault hook: KESTREL_TEST_WRITE_FAULT=STEP:FRAME (STEP one of open, chunk,
/// fsync, rename) makes the write of FRAME fail at that step as a full disk or a lost mount
/// would. Read once per writer, so it costs nothing per frame when unset.
std::pair<std::string, int64_t> faultFromEnvironment() {
    const char* env = std::getenv("KESTREL_TEST_WRITE_FAULT");
    if (!env) return {};
    const std::string text = env;
    const auto colon = text.find(':');
    if (colon == std::string::npos) return {};
    return {text.substr(0, colon), std::strtoll(text.c_str() + colon + 1, nullptr, 10)};
}

void ensureWritableFolder(const std::string& file) {
    fs::path dir = folderOf(file);
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw Error("cannot create output directory " + dir.string() + ": " + ec.message());
    fs::path probe = dir / (".kestrel-write-test-" + std::to_string(::getpid()));
    std::FILE* f = std::fopen(probe.c_str(), "wb");
    if (!f)
        throw Error("output directory " + dir.string() +
                    " is not writable: " + std::strerror(errno));
    std::fclose(f);
    fs::remove(probe, ec);
}
}  // namespace

PassDesc ExrWriter::describe() {
    PassDesc d("ExrWriter",
               "Writes each frame to an EXR file (atomically, with provenance) and optionally a "
               "tone-mapped PNG preview");
    d.input("color", Format::Any, "image to write (1-4 float channels as R,G,B,A; Int32 as id)");
    d.optionalInput("alpha", Format::Float,
                    "written as the A channel of a 3-channel color (the loader's alpha: the "
                    "input's coverage kept for compositing); unbound or absent: no A");
    d.paramString("path", "out/frame.####.exr", "output frame pattern (####, @, %04d)");
    d.paramEnum("pixelType", "auto", {"auto", "half", "float"},
                "EXR pixel type of float channels (ids are always float); auto: half where the "
                "source states its colour is half (the scene fact colorPixelType), else float, "
                "so the output keeps the input's precision");
    d.paramEnum("compression", "zip", kCompressions, "EXR compression");
    d.paramInt("zipLevel", 4, 1, 12,
               "deflate level of zip and zips (libdeflate): 1 fastest, 12 smallest; 4 is "
               "OpenEXR's default (1080p half RGB, 2 threads: see docs/benchmarks.md)");
    d.paramString("preview", "", "PNG preview pattern (empty: no preview)");
    d.paramFloat("exposure", 0.0, -20.0, 20.0, "preview exposure in stops");
    d.paramEnum("tonemap", "aces", {"aces", "reinhard", "clamp"},
                "preview tone curve (where $OCIO names no OpenColorIO config: with one, previews "
                "use its default display and view)");
    d.paramBool("keepPasses", false,
                "also write the input frame's other channels (its AOVs; not the colour and alpha "
                "this output replaces) and its header attributes (camera, frame, render stats), "
                "for a compositor; read from the loader's file, a block of rows at a time");
    d.sink = true;
    return d;
}

ExrWriter::ExrWriter(const ParamValues& p)
    : path_(p.getString("path")),
      pixelType_(p.getString("pixelType")),
      half_(pixelType_ == "half"),
      compression_(p.getString("compression")),
      zipLevel_(int(p.getInt("zipLevel"))),
      exposure_(p.getFloat("exposure")),
      keepPasses_(p.getBool("keepPasses")) {
    if (!p.getString("preview").empty()) {
        preview_ = std::make_unique<FramePattern>(p.getString("preview"));
        view_ = OcioView::fromEnvironment();
    }
    std::tie(faultStep_, faultFrame_) = faultFromEnvironment();
    const std::string& tm = p.getString("tonemap");
    toneMap_ = tm == "reinhard" ? ToneMap::Reinhard
               : tm == "clamp"  ? ToneMap::Clamp
                                : ToneMap::Aces;
}

void ExrWriter::resolve(ResolveContext& rc) {
    if (view_) rc.note("previews through OpenColorIO ($OCIO): " + view_->describe());
    if (keepPasses_) {
        kept_ = std::make_unique<KeptSource>(KeptSource::fromFacts(rc));
        rc.note("keeps the input's other channels and header attributes (keepPasses)");
    }
    if (pixelType_ != "auto") return;
    half_ = rc.fact("colorPixelType") == "half";
    // Float loses nothing and needs no word; half is said, since it rounds.
    if (half_) rc.note("writes half pixels, as the source's colour is (pixelType auto)");
}

void ExrWriter::beginRun(const RunContext& rc) {
    warnedRange_ = warnedNaN_ = false;
    ensureWritableFolder(path_.expand(rc.firstFrame));
    if (preview_) ensureWritableFolder(preview_->expand(rc.firstFrame));
}

bool ExrWriter::frameWritten(int64_t frame, const std::string& provenance) const {
    // A frame is written when every file it writes is complete and intact, and by this run's
    // graph and parameters: the EXR and its preview (a preview lost to a failed write was
    // never made again by --resume).
    const std::string file = path_.expand(frame);
    std::error_code ec;
    if (!fs::exists(file, ec)) return false;
    if (const std::string problem = exrProblem(file, provenance); !problem.empty()) {
        // --resume runs on from the first frame not written: a later frame is run again too.
        const bool foreign = problem.find("provenance") != std::string::npos;
        spdlog::warn("ExrWriter: {} {}; {} {} {}", file, problem, foreign ? "frames from" : "frame",
                     frame, foreign ? "on are run again" : "is written again");
        return false;
    }
    if (!preview_) return true;
    const std::string png = preview_->expand(frame);
    if (isCompletePng(png)) return true;
    spdlog::warn("ExrWriter: preview {} is missing or incomplete (a failed write?); frame {} is "
                 "written again",
                 png, frame);
    return false;
}

std::string ExrWriter::recordedProvenance(int64_t frame) const {
    try {
        // ExrInput: the header read safely (attribute sizes checked against the file's).
        const ExrInput in(path_.expand(frame), int64_t(1) << 40);
        const auto* p = in.header().findTypedAttribute<Imf::StringAttribute>("kestrel.provenance");
        return p ? p->value() : std::string();
    } catch (const std::exception&) {
        return {};
    }
}

namespace {
/// RGB colour and the alpha input as one RGBA view (no copy); the colour alone otherwise.
ImageView withAlpha(const ImageView& color, const PassIO& io) {
    if (color.format != Format::Float3 || !io.hasInput("alpha")) return color;
    ImageView rgba = color;
    rgba.format = Format::Float4;
    rgba.planes[3] = io.input("alpha").planes[0];
    return rgba;
}
}  // namespace

void ExrWriter::execute(FrameContext& ctx, PassIO& io) {
    if (!ctx.writeOutputs) return;
    const ImageView& img = io.input("color");
    std::string file = path_.expand(ctx.frameNumber);
    writeExr(withAlpha(img, io), file, ctx, {io.idlePlanes(), ctx.extent.pixels() * sizeof(float)});
    if (preview_) {
        std::string png = preview_->expand(ctx.frameNumber);
        std::string tmp = tempName(png);
        try {
            writePngPreview(img, tmp, exposure_, toneMap_, view_.get());
            syncToDisk(tmp, false);
            fs::rename(tmp, png);
        } catch (const std::exception& e) {
            std::error_code ec;
            fs::remove(tmp, ec);
            throw Error("cannot write preview " + png + ": " + e.what());
        }
    }
}

void ExrWriter::writeExr(const ImageView& img, const std::string& file, const FrameContext& ctx,
                         const Workspace& lent) {
    const int W = img.width(), H = img.height();
    const size_t N = img.pixels();
    const bool ids = img.format == Format::Int32;
    const int C = ids ? 1 : img.channels();
    if (C < 1 || C > 4 || W <= 0 || H <= 0)
        throw Error("cannot write " + file + ": unsupported image (" + std::to_string(C) +
                    " channels, " + std::to_string(W) + "x" + std::to_string(H) + ")");
    const bool asHalf = half_ && !ids;  // ids stay exact as float (half holds integers to 2048)

    // Sanitise while converting: NaN -> 0; beyond the half range (or +-Inf) -> the largest finite
    // value, so a file never holds Inf or NaN.
    std::atomic<size_t> nans{0}, clamped{0};
    const float limit = asHalf ? kHalfMax : std::numeric_limits<float>::max();
    // Values [b, e) of image channel c, converted into dst (half or float).
    auto convert = [&](int c, size_t b, size_t e, void* dst) {
        size_t localNaN = 0, localClamp = 0;
        const float* src = img.planes[size_t(c)];
        for (size_t i = b; i < e; ++i) {
            float v;
            if (ids) {
                v = float(reinterpret_cast<const int32_t*>(src)[i]);
            } else {
                v = src[i];
                if (std::isnan(v)) {
                    v = 0.f;
                    ++localNaN;
                } else if (std::fabs(v) > limit) {
                    v = std::copysign(limit, v);
                    ++localClamp;
                }
            }
            if (asHalf)
                static_cast<half*>(dst)[i - b] = half(v);
            else
                static_cast<float*>(dst)[i - b] = v;
        }
        if (localNaN) nans += localNaN;
        if (localClamp) clamped += localClamp;
    };
    const bool zip = compression_ == "zip" || compression_ == "zips";

    static const char* rgba[] = {"R", "G", "B", "A"};
    Imf::Header header(W, H);
    header.compression() = compressionOf(compression_);
    const Imf::PixelType type = asHalf ? Imf::HALF : Imf::FLOAT;
    const size_t elem = asHalf ? sizeof(half) : sizeof(float);
    for (int c = 0; c < C; ++c) header.channels().insert(ids ? "id" : rgba[c], Imf::Channel(type));
    // Rec.709 primaries and D65 white (Blender's and most renderers' scene-linear): without
    // the attribute a compositor or OCIO-aware viewer has to guess the colour space.
    if (!ids) Imf::addChromaticities(header, kRec709);
    if (ctx.run) {
        header.insert("kestrel.graph", Imf::StringAttribute(ctx.run->graphName));
        header.insert("kestrel.provenance", Imf::StringAttribute(ctx.run->provenance));
    }
    header.insert(kCrcAttribute, Imf::StringAttribute(kCrcPlaceholder));  // filled once written
    // The image channel of each of the header's (alphabetically ordered) channels.
    std::vector<int> channelOf;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it)
        for (int c = 0; c < C; ++c)
            if (std::strcmp(it.name(), ids ? "id" : rgba[c]) == 0) channelOf.push_back(c);

    int threads = ctx.parallel ? ctx.parallel->threadCount() : 1;
    std::string tmp = tempName(file);
    const int64_t frame = ctx.frameNumber;
    try {
        injectFault("open", frame);
        if (kept_) {
            const OwnRow own = [&](const std::string& name, int y, void* dst) {
                const auto c = std::find(std::begin(rgba), std::end(rgba), name) - std::begin(rgba);
                convert(ids ? 0 : int(c), size_t(y) * size_t(W), size_t(y + 1) * size_t(W), dst);
            };
            writeKeeping(header, tmp, frame, own, threads);
        } else if (zip) {
            // Converted a scan line at a time as the encoder asks: no frame-sized copy.
            const ZipRowSource rows = [&](size_t ch, size_t row, unsigned char* dst) {
                convert(channelOf[ch], row * size_t(W), (row + 1) * size_t(W), dst);
            };
            ZipChunkHook hook;
            if (faultStep_ == "chunk" && faultFrame_ == frame)
                hook = [this, frame](size_t chunk) {
                    if (chunk == 1) injectFault("chunk", frame);  // after one chunk is on disk
                };
            writeZipScanlines(tmp, header, rows, threads, zipLevel_, hook, lent);
        } else {
            if (asHalf)
                halfScratch_.resize(N * size_t(C));
            else
                floatScratch_.resize(N * size_t(C));
            char* data = asHalf ? reinterpret_cast<char*>(halfScratch_.data())
                                : reinterpret_cast<char*>(floatScratch_.data());
            ctx.parallelRows(H, [&](int y0, int y1) {
                for (int c = 0; c < C; ++c) {
                    const size_t b = size_t(y0) * size_t(W), e = size_t(y1) * size_t(W);
                    convert(c, b, e, data + (size_t(c) * N + b) * elem);
                }
            });
            Imf::FrameBuffer fb;
            for (int c = 0; c < C; ++c)
                fb.insert(ids ? "id" : rgba[c],
                          Imf::Slice(type, data + size_t(c) * N * elem, elem, elem * size_t(W)));
            if (Imf::globalThreadCount() < threads) Imf::setGlobalThreadCount(threads);
            Imf::OutputFile out(tmp.c_str(), header, Imf::globalThreadCount());
            out.setFrameBuffer(fb);
            out.writePixels(H);
        }  // closed before it is checksummed, flushed and renamed
        stampChecksum(tmp, headerEndOf(tmp));
        injectFault("fsync", frame);
        syncToDisk(tmp, false);
        injectFault("rename", frame);
        fs::rename(tmp, file);
        syncToDisk(folderOf(file).string(), true);  // the rename itself survives a power loss
    } catch (const std::exception& e) {
        std::error_code ec;
        fs::remove(tmp, ec);
        throw Error("cannot write " + file + ": " + e.what());
    }
    warnSanitised(ctx.frameNumber, nans, clamped, asHalf, limit);
}

void ExrWriter::writeKeeping(const Imf::Header& header, const std::string& tmp, int64_t frame,
                             const OwnRow& own, int threads) const {
    // The output's A replaces the input's alpha only when there is one.
    std::set<std::string> replaced = kept_->color;
    if (header.channels().findChannel("A"))
        replaced.insert(kept_->alpha.begin(), kept_->alpha.end());
    if (Imf::globalThreadCount() < threads) Imf::setGlobalThreadCount(threads);
    const std::string input = kept_->pattern.expand(frame);
    try {
        writeKeepingPasses(tmp, header, input, replaced, own, Imf::globalThreadCount());
    } catch (const Error& e) {
        throw Error("keepPasses: input " + input + ": " + e.what());
    }
}

void ExrWriter::warnSanitised(int64_t frameNumber, size_t nans, size_t clamped, bool asHalf,
                              float limit) {
    if (clamped && !warnedRange_) {
        spdlog::warn(
            "ExrWriter: frame {}: {} values beyond the {} range clamped to +-{} (warned "
            "once per run)",
            frameNumber, clamped, asHalf ? "half" : "float", limit);
        warnedRange_ = true;
    }
    if (nans && !warnedNaN_) {
        spdlog::warn("ExrWriter: frame {}: {} NaN values written as 0 (warned once per run)",
                     frameNumber, nans);
        warnedNaN_ = true;
    }
}

void ExrWriter::injectFault(const char* step, int64_t frame) const {
    if (frame == faultFrame_ && faultStep_ == step)
        throw Error(std::string("injected fault at step '") + step +
                    "' (KESTREL_TEST_WRITE_FAULT)");
}

}  // namespace kestrel::exr
