#include "exr_test_util.h"

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfTiledOutputFile.h>
#include <unistd.h>

#include "kestrel/Error.h"

namespace exrtest {

TempDir::TempDir(const std::string& name)
    : path(fs::temp_directory_path() / ("kestrel_exr_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
}
TempDir::~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
}

void writeExr(const fs::path& file, const Imath::Box2i& dw, const Channels& channels,
              const WriteOptions& opt, const Imf::Header* extra) {
    Imath::Box2i display = opt.display.isEmpty() ? dw : opt.display;
    Imf::Header h(display, dw);
    if (extra)
        for (auto it = extra->begin(); it != extra->end(); ++it)
            if (std::string(it.name()).rfind("kestrel.", 0) == 0)
                h.insert(it.name(), it.attribute());
    h.compression() = opt.compression;
    const int w = dw.max.x - dw.min.x + 1;
    Imf::FrameBuffer fb;
    std::vector<std::vector<half>> halves;  // output files take the file's own pixel type
    halves.reserve(channels.size());
    for (const auto& [name, values] : channels) {
        h.channels().insert(name, Imf::Channel(opt.type));
        const size_t origin = size_t(dw.min.x + ptrdiff_t(dw.min.y) * w);
        if (opt.type == Imf::HALF) {
            halves.emplace_back(values.begin(), values.end());
            char* base = (char*)(halves.back().data()) - origin * sizeof(half);
            fb.insert(name, Imf::Slice(Imf::HALF, base, sizeof(half), sizeof(half) * size_t(w)));
        } else {
            char* base = (char*)(values.data()) - origin * sizeof(float);
            fb.insert(name, Imf::Slice(Imf::FLOAT, base, sizeof(float), sizeof(float) * size_t(w)));
        }
    }
    if (opt.tiled) {
        h.setTileDescription(Imf::TileDescription(16, 16, Imf::ONE_LEVEL));
        Imf::TiledOutputFile out(file.c_str(), h);
        out.setFrameBuffer(fb);
        out.writeTiles(0, out.numXTiles() - 1, 0, out.numYTiles() - 1);
    } else {
        Imf::OutputFile out(file.c_str(), h);
        out.setFrameBuffer(fb);
        out.writePixels(dw.max.y - dw.min.y + 1);
    }
}

std::vector<float> readChannel(const fs::path& file, const std::string& channel) {
    Imf::InputFile in(file.c_str());
    auto dw = in.header().dataWindow();
    const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
    std::vector<float> v(size_t(w) * size_t(h));
    Imf::FrameBuffer fb;
    char* base = (char*)(v.data()) - (dw.min.x + size_t(dw.min.y) * w) * sizeof(float);
    fb.insert(channel, Imf::Slice(Imf::FLOAT, base, sizeof(float), sizeof(float) * size_t(w)));
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    return v;
}

void readAllChannels(const fs::path& file) {
    Imf::InputFile in(file.c_str());
    auto dw = in.header().dataWindow();
    const size_t w = size_t(dw.max.x - dw.min.x + 1), h = size_t(dw.max.y - dw.min.y + 1);
    std::vector<std::vector<float>> planes;
    planes.reserve(in.header().channels().end() == in.header().channels().begin() ? 0 : 256);
    Imf::FrameBuffer fb;
    for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it) {
        planes.emplace_back(w * h);
        char* base =
            (char*)(planes.back().data()) - (dw.min.x + ptrdiff_t(dw.min.y) * ptrdiff_t(w)) * 4;
        fb.insert(it.name(), Imf::Slice(Imf::FLOAT, base, 4, 4 * w));
    }
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
}

std::string sharedData(const std::string& name) {
    fs::path p = fs::path(KESTREL_SHARED_DIR) / "data" / name;
    std::error_code ec;
    return fs::exists(p, ec) ? p.string() : std::string();
}

std::string resolveError(kestrel::Pass& pass) {
    RecordingResolve rc(1);
    try {
        pass.resolve(rc);
    } catch (const kestrel::Error& e) {
        return e.what();
    }
    return "";
}

}  // namespace exrtest
