#include "eval/ExrRgb.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <kestrel/Error.h>
#include <kestrel/InputFiles.h>

#include <algorithm>
#include <cctype>
#include <map>
#include <set>
#include <system_error>

namespace kestrel::eval {
namespace {

std::string joinQuoted(const std::vector<std::string>& names, size_t maxCount = 12) {
    std::string s;
    for (size_t i = 0; i < names.size() && i < maxCount; ++i)
        s += (i ? ", " : "") + (names[i].empty() ? std::string("(plain R,G,B)") : names[i]);
    if (names.size() > maxCount) s += ", ... (" + std::to_string(names.size()) + " in all)";
    return s;
}

/// Whether the file name ends in .exr, in any case (everything else goes to OpenImageIO).
bool isExrName(const std::filesystem::path& path) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return std::tolower(c); });
    return ext == ".exr";
}

std::string channelName(const std::string& prefix, char c) {
    return prefix.empty() ? std::string(1, c) : prefix + "." + c;
}

}  // namespace

std::string chooseRgbLayer(const std::vector<std::string>& channelNames, std::string_view layer) {
    std::map<std::string, int> found;  // prefix -> bit mask of R, G, B
    for (const std::string& name : channelNames) {
        const size_t dot = name.rfind('.');
        const std::string prefix = dot == std::string::npos ? std::string() : name.substr(0, dot);
        const std::string comp = dot == std::string::npos ? name : name.substr(dot + 1);
        if (comp == "R") found[prefix] |= 1;
        if (comp == "G") found[prefix] |= 2;
        if (comp == "B") found[prefix] |= 4;
    }
    std::vector<std::string> rgb;
    for (const auto& [prefix, mask] : found)
        if (mask == 7) rgb.push_back(prefix);

    auto lastComponent = [](const std::string& p) {
        const size_t dot = p.rfind('.');
        return dot == std::string::npos ? p : p.substr(dot + 1);
    };
    std::vector<std::string> fits;
    if (!layer.empty()) {
        const std::string suffix = "." + std::string(layer);
        for (const std::string& p : rgb)
            if (p == layer || (p.size() > suffix.size() && p.ends_with(suffix))) fits.push_back(p);
        if (fits.empty())
            throw Error("no RGB layer '" + std::string(layer) + "'" +
                        (rgb.empty() ? std::string(" (the file has no R,G,B channels)")
                                     : " (RGB layers: " + joinQuoted(rgb) + ")"));
    } else {
        if (found.count("") && found[""] == 7) return "";
        for (const std::string& p : rgb)
            if (lastComponent(p) == "Combined") fits.push_back(p);
        if (fits.empty()) fits = rgb;
        if (fits.empty()) {
            std::vector<std::string> some(channelNames.begin(), channelNames.end());
            throw Error("no R,G,B channels (channels: " + joinQuoted(some) + ")");
        }
    }
    if (fits.size() > 1)
        throw Error("several RGB layers fit (" + joinQuoted(fits) + "); choose one with --layer");
    return fits.front();
}

Image readExrRgb(const std::filesystem::path& path, std::string_view layer) {
    const std::string where = "'" + path.string() + "'";
    try {
        checkRegularFile(path, "EXR file");  // a FIFO would block the open forever
    } catch (const Error& e) {
        throw FrameError(e.what());
    }
    if (!isExrName(path)) return readImageRgb(path);
    try {
        Imf::InputFile file(path.c_str());
        const Imf::Header& header = file.header();
        std::vector<std::string> names;
        for (auto it = header.channels().begin(); it != header.channels().end(); ++it)
            names.emplace_back(it.name());
        std::string prefix;
        try {
            prefix = chooseRgbLayer(names, layer);
        } catch (const Error& e) {
            throw FrameError(where + ": " + e.what());
        }
        const Imath::Box2i dw = header.dataWindow();
        const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
        if (w <= 0 || h <= 0) throw FrameError(where + ": empty data window");
        Image image(w, h, Format::Float3);
        Imf::FrameBuffer fb;
        const char comps[3] = {'R', 'G', 'B'};
        for (int c = 0; c < 3; ++c)
            fb.insert(channelName(prefix, comps[c]),
                      Imf::Slice::Make(Imf::FLOAT, image.channel(c), dw, sizeof(float),
                                       sizeof(float) * size_t(w)));
        file.setFrameBuffer(fb);
        file.readPixels(dw.min.y, dw.max.y);
        return image;
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        throw FrameError("cannot read EXR " + where + ": " + e.what());
    }
}

}  // namespace kestrel::eval
