#pragma once
// Test helper: reads every channel of a scanline EXR as float planes, and its header.
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

struct ExrImage {
    int width = 0, height = 0;
    std::map<std::string, std::vector<float>> channels;
    std::map<std::string, int> types;  // Imf::PixelType per channel
    Imf::Header header;
};

inline ExrImage readExr(const std::filesystem::path& path) {
    Imf::InputFile file(path.c_str());
    ExrImage img;
    img.header = file.header();
    const auto dw = img.header.dataWindow();
    img.width = dw.max.x - dw.min.x + 1;
    img.height = dw.max.y - dw.min.y + 1;
    Imf::FrameBuffer fb;
    for (auto it = img.header.channels().begin(); it != img.header.channels().end(); ++it) {
        auto& plane = img.channels[it.name()];
        plane.assign(size_t(img.width) * size_t(img.height), 0.f);
        img.types[it.name()] = int(it.channel().type);
        fb.insert(it.name(), Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(plane.data()),
                                        sizeof(float), sizeof(float) * size_t(img.width)));
    }
    file.setFrameBuffer(fb);
    file.readPixels(dw.min.y, dw.max.y);
    return img;
}

inline std::vector<std::string> channelNames(const ExrImage& img) {
    std::vector<std::string> names;
    for (const auto& [name, plane] : img.channels) names.push_back(name);
    return names;
}
