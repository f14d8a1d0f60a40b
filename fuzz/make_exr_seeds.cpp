// Writes the EXR seed corpus of exr_fuzzer (fuzz/corpus/exr_fuzzer/): tiny files (<= 20 KB)
// covering the layouts the loader detects (canonical with every AOV, Blender multilayer names,
// plain RGB), every scanline compression, half/float/uint channels, tiles, mipmaps, offset data
// windows and multi-part files. Deterministic. Build and run by hand:
//   g++ -std=c++17 fuzz/make_exr_seeds.cpp $(pkg-config --cflags --libs OpenEXR) -o make_exr_seeds
//   ./make_exr_seeds fuzz/corpus/exr_fuzzer
#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfMultiPartOutputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfOutputPart.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfTiledOutputFile.h>

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace {

struct Plane {
    std::string name;
    Imf::PixelType type;
    std::vector<float> f;
    std::vector<unsigned> u;
    std::vector<half> h;
};

std::vector<Plane> planes(const std::vector<std::string>& names, Imf::PixelType type, int n) {
    std::vector<Plane> out;
    int k = 0;
    for (const auto& name : names) {
        Plane p{name, type, {}, {}, {}};
        for (int i = 0; i < n; ++i) {
            const float v = name.find("id") != std::string::npos ? float(i % 3 - 1)
                            : name.find("Z") != std::string::npos && name.find("depth") == 0
                                ? 1.f + float(i)
                                : 0.1f * float((i * 7 + k * 3) % 11) - 0.2f;
            p.f.push_back(v);
            p.h.push_back(half(v));
            p.u.push_back(unsigned(i * 5 + k));
        }
        out.push_back(std::move(p));
        ++k;
    }
    return out;
}

void fill(Imf::Header& hdr, Imf::FrameBuffer& fb, std::vector<Plane>& ps, int x0, int y0, int w) {
    for (auto& p : ps) {
        hdr.channels().insert(p.name, Imf::Channel(p.type));
        char* base = p.type == Imf::FLOAT  ? reinterpret_cast<char*>(p.f.data())
                     : p.type == Imf::HALF ? reinterpret_cast<char*>(p.h.data())
                                           : reinterpret_cast<char*>(p.u.data());
        const size_t e = p.type == Imf::HALF ? 2 : 4;
        fb.insert(p.name, Imf::Slice(p.type, base - (x0 + y0 * w) * e, e, e * size_t(w)));
    }
}

void scanline(const std::string& path, int w, int h, const std::vector<std::string>& names,
              Imf::PixelType type, Imf::Compression c, int ox = 0, int oy = 0,
              const char* layoutTag = nullptr) {
    Imf::Header hdr(Imath::Box2i({0, 0}, {w - 1 + ox, h - 1 + oy}),
                    Imath::Box2i({ox, oy}, {ox + w - 1, oy + h - 1}));
    hdr.compression() = c;
    if (layoutTag) hdr.insert("kestrel.layout", Imf::StringAttribute(layoutTag));
    auto ps = planes(names, type, w * h);
    Imf::FrameBuffer fb;
    fill(hdr, fb, ps, ox, oy, w);
    Imf::OutputFile out(path.c_str(), hdr);
    out.setFrameBuffer(fb);
    out.writePixels(h);
}

void tiled(const std::string& path, int w, int h, Imf::LevelMode mode) {
    Imf::Header hdr(w, h);
    hdr.setTileDescription(Imf::TileDescription(4, 4, mode));
    auto ps = planes({"R", "G", "B"}, Imf::HALF, w * h);
    Imf::FrameBuffer fb;
    fill(hdr, fb, ps, 0, 0, w);
    Imf::TiledOutputFile out(path.c_str(), hdr);
    out.setFrameBuffer(fb);
    out.writeTiles(0, out.numXTiles(0) - 1, 0, out.numYTiles(0) - 1);  // level 0 only
}

void multipart(const std::string& path) {
    std::vector<Imf::Header> headers(2, Imf::Header(3, 2));
    headers[0].setName("beauty");
    headers[1].setName("aux");
    headers[0].setType(Imf::SCANLINEIMAGE);
    headers[1].setType(Imf::SCANLINEIMAGE);
    auto p0 = planes({"R", "G", "B"}, Imf::FLOAT, 6), p1 = planes({"depth.Z"}, Imf::FLOAT, 6);
    Imf::FrameBuffer fb0, fb1;
    fill(headers[0], fb0, p0, 0, 0, 3);
    fill(headers[1], fb1, p1, 0, 0, 3);
    Imf::MultiPartOutputFile out(path.c_str(), headers.data(), 2);
    Imf::OutputPart a(out, 0), b(out, 1);
    a.setFrameBuffer(fb0);
    a.writePixels(2);
    b.setFrameBuffer(fb1);
    b.writePixels(2);
}

/// Copies `from` to `to` with its data and display windows forged to w x h, pixels unchanged:
/// a header declaring far more than the file holds (the loader must refuse it before allocating).
void oversized(const std::string& from, const std::string& to, int32_t w, int32_t h) {
    std::ifstream in(from, std::ios::binary);
    std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    for (const std::string name : {"dataWindow", "displayWindow"}) {
        const std::string key = name + '\0' + "box2i" + '\0';
        const auto at = bytes.find(key);
        if (at == std::string::npos) return;
        const int32_t box[4] = {0, 0, w - 1, h - 1};  // little-endian hosts only, as the seeds
        bytes.replace(at + key.size() + 4, sizeof box, reinterpret_cast<const char*>(box),
                      sizeof box);
    }
    std::ofstream(to, std::ios::binary) << bytes;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: %s <dir>\n", argv[0]);
        return 2;
    }
    const std::string d = std::string(argv[1]) + "/";
    const std::vector<std::string> canonical = {
        "R",          "G",          "B",          "albedo.R",   "albedo.G",
        "albedo.B",   "emission.R", "emission.G", "emission.B", "direct.R",
        "direct.G",   "direct.B",   "indirect.R", "indirect.G", "indirect.B",
        "normal.X",   "normal.Y",   "normal.Z",   "depth.Z",    "position.X",
        "position.Y", "position.Z", "motion.X",   "motion.Y",   "objectId.id"};
    scanline(d + "canonical-4x3-zip.exr", 4, 3, canonical, Imf::FLOAT, Imf::ZIP_COMPRESSION, 0, 0,
             "canonical");
    scanline(d + "canonical-2x2-none-half.exr", 2, 2, canonical, Imf::HALF, Imf::NO_COMPRESSION, 0,
             0, "canonical");
    const std::vector<std::string> blender = {
        "ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B",
        "ViewLayer.Combined.A", "ViewLayer.Depth.Z",    "ViewLayer.Normal.X",
        "ViewLayer.Normal.Y",   "ViewLayer.Normal.Z",   "ViewLayer.DiffCol.R",
        "ViewLayer.DiffCol.G",  "ViewLayer.DiffCol.B",  "ViewLayer.Vector.X",
        "ViewLayer.Vector.Y",   "ViewLayer.Vector.Z",   "ViewLayer.Vector.W",
        "ViewLayer.IndexOB.X"};
    scanline(d + "blender-3x2-zip.exr", 3, 2, blender, Imf::FLOAT, Imf::ZIP_COMPRESSION);
    const Imf::Compression all[] = {
        Imf::NO_COMPRESSION,   Imf::RLE_COMPRESSION,   Imf::ZIPS_COMPRESSION, Imf::ZIP_COMPRESSION,
        Imf::PIZ_COMPRESSION,  Imf::PXR24_COMPRESSION, Imf::B44_COMPRESSION,  Imf::B44A_COMPRESSION,
        Imf::DWAA_COMPRESSION, Imf::DWAB_COMPRESSION};
    const char* names[] = {"none",  "rle", "zips", "zip",  "piz",
                           "pxr24", "b44", "b44a", "dwaa", "dwab"};
    for (int i = 0; i < 10; ++i)
        scanline(d + "rgb-5x3-" + names[i] + ".exr", 5, 3, {"R", "G", "B"}, Imf::HALF, all[i]);
    scanline(d + "rgba-float-offset.exr", 3, 3, {"R", "G", "B", "A"}, Imf::FLOAT,
             Imf::ZIP_COMPRESSION, 2, 1);
    scanline(d + "uint-channels.exr", 2, 3, {"R", "G", "B", "objectId.id"}, Imf::UINT,
             Imf::RLE_COMPRESSION);
    scanline(d + "y-only.exr", 4, 1, {"Y"}, Imf::HALF, Imf::NO_COMPRESSION);
    tiled(d + "tiled-6x5.exr", 6, 5, Imf::ONE_LEVEL);
    multipart(d + "multipart.exr");
    // Headers declaring far more than the file: 4000x4000 (1.6 GB of pixels in a 2 KB file)
    // and 4 x 1,000,000 (an offset table of 500 KB past the end of the file).
    oversized(d + "canonical-4x3-zip.exr", d + "oversized-window-4000x4000.exr", 4000, 4000);
    oversized(d + "canonical-4x3-zip.exr", d + "oversized-window-4x1000000.exr", 4, 1000000);
    return 0;
}
