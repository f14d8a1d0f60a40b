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
#include "WriterIntegrity.h"
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

ExrWriter::Declaration::Declaration()
    : kestrel::Declaration<Params>(
          "ExrWriter",
          "Writes each frame to an EXR file (atomically, with provenance) and optionally a "
          "tone-mapped PNG preview") {
    color =
        input("color", Format::Any, "image to write (1-4 float channels as R,G,B,A; Int32 as id)");
    alpha = optionalInput("alpha", Format::Float,
                          "written as the A channel of a 3-channel color (the loader's alpha: the "
                          "input's coverage kept for compositing); unbound or absent: no A");
    param("path", &Params::path, "output frame pattern (####, @, %04d)");
    param("pixelType", &Params::pixelType, {"auto", "half", "float"},
          "EXR pixel type of float channels (ids are always float); auto: half where the source "
          "states its colour is half (the scene fact colorPixelType), else float, so the output "
          "keeps the input's precision");
    param("compression", &Params::compression, kCompressions, "EXR compression");
    param("zipLevel", &Params::zipLevel, 1, 12,
          "deflate level of zip and zips (libdeflate): 1 fastest, 12 smallest; 4 is OpenEXR's "
          "default (1080p half RGB, 2 threads: see docs/benchmarks.md)");
    param("preview", &Params::preview, "PNG preview pattern (empty: no preview)");
    param("exposure", &Params::exposure, -20.0, 20.0, "preview exposure in stops");
    param("tonemap", &Params::tonemap, display::toneCurveNames(),
          "preview tone curve (where $OCIO names no OpenColorIO config: with one, previews use "
          "its default display and view)");
    param("keepPasses", &Params::keepPasses,
          "also write the input frame's other channels (its AOVs; not the colour and alpha this "
          "output replaces) and its header attributes (camera, frame, render stats), for a "
          "compositor; read from the loader's file, a block of rows at a time");
    declareSink();
}

const ExrWriter::Declaration& ExrWriter::declaration() {
    static const Declaration d;
    return d;
}

ExrWriter::ExrWriter(const ParamValues& params)
    : p_(declaration().read(params)), path_(p_.path), half_(p_.pixelType == PixelType::Half) {
    if (!p_.preview.empty()) {
        preview_ = std::make_unique<FramePattern>(p_.preview);
        view_ = OcioView::fromEnvironment();
    }
    std::tie(faultStep_, faultFrame_) = faultFromEnvironment();
}

void ExrWriter::resolve(ResolveContext& rc) {
    if (view_) rc.note("previews through OpenColorIO ($OCIO): " + view_->describe());
    if (p_.keepPasses) {
        kept_ = std::make_unique<KeptSource>(KeptSource::fromFacts(rc));
        rc.note("keeps the input's other channels and header attributes (keepPasses)");
    }
    if (p_.pixelType != PixelType::Auto) return;
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
    spdlog::warn(
        "ExrWriter: preview {} is missing or incomplete (a failed write?); frame {} is "
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
    const InputPort& alpha = ExrWriter::declaration().alpha;
    if (color.format != Format::Float3 || !io.has(alpha)) return color;
    ImageView rgba = color;
    rgba.format = Format::Float4;
    rgba.planes[3] = io.input(alpha).planes[0];
    return rgba;
}
}  // namespace

void ExrWriter::execute(FrameContext& ctx, PassIO& io) {
    if (!ctx.writeOutputs) return;
    const ImageView& img = io.input(declaration().color);
    std::string file = path_.expand(ctx.frameNumber);
    writeExr(withAlpha(img, io), file, ctx, {io.idlePlanes(), ctx.extent.pixels() * sizeof(float)});
    if (preview_) {
        std::string png = preview_->expand(ctx.frameNumber);
        std::string tmp = tempName(png);
        try {
            writePngPreview(img, tmp, p_.exposure, p_.tonemap, view_.get());
            syncToDisk(tmp, false);
            fs::rename(tmp, png);
        } catch (const std::exception& e) {
            std::error_code ec;
            fs::remove(tmp, ec);
            throw Error("cannot write preview " + png + ": " + e.what());
        }
    }
}

/// Image channel c's values [b, e), converted into dst (half or float), sanitised: NaN -> 0;
/// beyond the half range (or +-Inf) -> the largest finite value, so a file never holds Inf or
/// NaN. Counts what it changed.
struct ExrWriter::Converter {
    const ImageView& img;
    bool ids, asHalf;
    float limit;
    std::atomic<size_t> nans{0}, clamped{0};

    void operator()(int c, size_t b, size_t e, void* dst) {
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
    }
};

namespace {
const char* const kRgba[] = {"R", "G", "B", "A"};

/// The output's header: C channels (R, G, B, A or id), Rec.709 chromaticities, the run's
/// provenance and the checksum's placeholder.
Imf::Header exrHeader(int W, int H, int C, bool ids, bool asHalf, const std::string& compression,
                      const FrameContext& ctx) {
    Imf::Header header(W, H);
    header.compression() = compressionOf(compression);
    const Imf::PixelType type = asHalf ? Imf::HALF : Imf::FLOAT;
    for (int c = 0; c < C; ++c) header.channels().insert(ids ? "id" : kRgba[c], Imf::Channel(type));
    // Rec.709 primaries and D65 white (Blender's and most renderers' scene-linear): without
    // the attribute a compositor or OCIO-aware viewer has to guess the colour space.
    if (!ids) Imf::addChromaticities(header, kRec709);
    if (ctx.run) {
        header.insert("kestrel.graph", Imf::StringAttribute(ctx.run->graphName));
        header.insert("kestrel.provenance", Imf::StringAttribute(ctx.run->provenance));
    }
    header.insert(kCrcAttribute, Imf::StringAttribute(kCrcPlaceholder));  // filled once written
    return header;
}
}  // namespace

void ExrWriter::writeExr(const ImageView& img, const std::string& file, const FrameContext& ctx,
                         const Workspace& lent) {
    const int W = img.width(), H = img.height();
    const bool ids = img.format == Format::Int32;
    const int C = ids ? 1 : img.channels();
    if (C < 1 || C > 4 || W <= 0 || H <= 0)
        throw Error("cannot write " + file + ": unsupported image (" + std::to_string(C) +
                    " channels, " + std::to_string(W) + "x" + std::to_string(H) + ")");
    const bool asHalf = half_ && !ids;  // ids stay exact as float (half holds integers to 2048)
    Converter convert{img, ids, asHalf, asHalf ? kHalfMax : std::numeric_limits<float>::max()};
    const bool zip = p_.compression == "zip" || p_.compression == "zips";
    const Imf::Header header = exrHeader(W, H, C, ids, asHalf, p_.compression, ctx);
    // The image channel of each of the header's (alphabetically ordered) channels.
    std::vector<int> channelOf;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it)
        for (int c = 0; c < C; ++c)
            if (std::strcmp(it.name(), ids ? "id" : kRgba[c]) == 0) channelOf.push_back(c);

    int threads = ctx.parallel ? ctx.parallel->threadCount() : 1;
    std::string tmp = tempName(file);
    const int64_t frame = ctx.frameNumber;
    try {
        injectFault("open", frame);
        if (kept_) {
            const OwnRow own = [&](const std::string& name, int y, void* dst) {
                const auto c =
                    std::find(std::begin(kRgba), std::end(kRgba), name) - std::begin(kRgba);
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
            writeZipScanlines(tmp, header, rows, threads, p_.zipLevel, hook, lent);
        } else {
            writeThroughOpenExr(header, tmp, convert, ctx);
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
    warnSanitised(ctx.frameNumber, convert.nans, convert.clamped, asHalf, convert.limit);
}

void ExrWriter::writeThroughOpenExr(const Imf::Header& header, const std::string& tmp,
                                    Converter& convert, const FrameContext& ctx) {
    const ImageView& img = convert.img;
    const int W = img.width(), H = img.height();
    const size_t N = img.pixels();
    const int C = convert.ids ? 1 : img.channels();
    const bool asHalf = convert.asHalf;
    const Imf::PixelType type = asHalf ? Imf::HALF : Imf::FLOAT;
    const size_t elem = asHalf ? sizeof(half) : sizeof(float);
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
        fb.insert(convert.ids ? "id" : kRgba[c],
                  Imf::Slice(type, data + size_t(c) * N * elem, elem, elem * size_t(W)));
    const int threads = ctx.parallel ? ctx.parallel->threadCount() : 1;
    if (Imf::globalThreadCount() < threads) Imf::setGlobalThreadCount(threads);
    Imf::OutputFile out(tmp.c_str(), header, Imf::globalThreadCount());
    out.setFrameBuffer(fb);
    out.writePixels(H);
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
