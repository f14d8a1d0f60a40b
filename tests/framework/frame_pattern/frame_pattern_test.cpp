#include <gtest/gtest.h>
#include <kestrel/Error.h>
#include <kestrel/FramePattern.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

using kestrel::Error;
using kestrel::FramePattern;
using kestrel::parseFrameRange;
namespace fs = std::filesystem;

TEST(FramePattern, HashRunIsItsLengthAndLoneHashIsFourDigits) {
    EXPECT_EQ(FramePattern("frame.####.exr").expand(7), "frame.0007.exr");
    EXPECT_EQ(FramePattern("frame.#.exr").expand(7), "frame.0007.exr");
    EXPECT_EQ(FramePattern("frame.######.exr").expand(123), "frame.000123.exr");
    EXPECT_EQ(FramePattern("frame.####.exr").expand(12345), "frame.12345.exr");
}

TEST(FramePattern, AtIsOneDigitEach) {
    EXPECT_EQ(FramePattern("f.@.exr").expand(3), "f.3.exr");
    EXPECT_EQ(FramePattern("f.@@@.exr").expand(3), "f.003.exr");
}

TEST(FramePattern, PrintfStyle) {
    EXPECT_EQ(FramePattern("dir/frame_%04d.exr").expand(12), "dir/frame_0012.exr");
    EXPECT_EQ(FramePattern("beauty_%d.exr").expand(0), "beauty_0.exr");
    EXPECT_EQ(FramePattern("beauty_%d.exr").expand(19), "beauty_19.exr");
    EXPECT_EQ(FramePattern("a%%b_%02d.exr").expand(5), "a%b_05.exr");
}

TEST(FramePattern, NegativeFramesAndNoToken) {
    EXPECT_EQ(FramePattern("f.####.exr").expand(-3), "f.-003.exr");
    FramePattern still("still.exr");
    EXPECT_FALSE(still.hasFrameToken());
    EXPECT_EQ(still.expand(42), "still.exr");
    EXPECT_TRUE(still.findFrames().empty());
}

TEST(FramePattern, MatchRequiresThePatternsPadding) {
    FramePattern p("out/frame.####.exr");
    EXPECT_EQ(p.match("out/frame.0007.exr"), 7);
    EXPECT_EQ(p.match("out/frame.12345.exr"), 12345);
    EXPECT_EQ(p.match("out/frame.7.exr"), std::nullopt);
    EXPECT_EQ(p.match("out/frame.00007.exr"), std::nullopt);
    EXPECT_EQ(p.match("out/frame.00a7.exr"), std::nullopt);
    EXPECT_EQ(p.match("out/frame.0007.png"), std::nullopt);
    FramePattern u("beauty_%d.exr");
    EXPECT_EQ(u.match("beauty_10.exr"), 10);
    EXPECT_EQ(u.match("beauty_010.exr"), std::nullopt);
}

TEST(FramePattern, BadSyntaxIsAnErrorNamingIt) {
    auto message = [](const char* pat) {
        try {
            FramePattern p(pat);
        } catch (const Error& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_NE(message("a.%5x.exr").find("a.%5x.exr"), std::string::npos);
    EXPECT_NE(message("a.%5d.exr").find("only %d and %0Nd"), std::string::npos);
    EXPECT_NE(message("a.####.b.%04d.exr").find("second frame token"), std::string::npos);
    EXPECT_NE(message("a.%0d.exr").find("width"), std::string::npos);
    EXPECT_NE(message("trailing%").find("trailing%"), std::string::npos);
}

TEST(FramePattern, FindFramesListsExistingFilesSorted) {
    fs::path dir = fs::temp_directory_path() / ("kestrel_fp_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir / "sub.0003.exr");  // a directory is not a frame
    for (const char* n : {"f.0010.exr", "f.0002.exr", "f.7.exr", "f.0004.exr.tmp", "g.0001.exr"})
        std::ofstream(dir / n) << "x";
    EXPECT_EQ(FramePattern((dir / "f.####.exr").string()).findFrames(),
              (std::vector<int64_t>{2, 10}));
    EXPECT_EQ(kestrel::findFrames((dir / "f.%d.exr").string()), (std::vector<int64_t>{7}));
    EXPECT_TRUE(FramePattern((dir / "missing/f.####.exr").string()).findFrames().empty());
    fs::remove_all(dir);
}

TEST(FrameRange, Forms) {
    EXPECT_EQ(parseFrameRange("5"), (std::vector<int64_t>{5}));
    EXPECT_EQ(parseFrameRange("1-4"), (std::vector<int64_t>{1, 2, 3, 4}));
    EXPECT_EQ(parseFrameRange("1-7x3"), (std::vector<int64_t>{1, 4, 7}));
    EXPECT_EQ(parseFrameRange("3,4,10-20x5"), (std::vector<int64_t>{3, 4, 10, 15, 20}));
    EXPECT_EQ(parseFrameRange("-2--1"), (std::vector<int64_t>{-2, -1}));
    EXPECT_EQ(parseFrameRange("1-100").size(), 100u);
    EXPECT_EQ(parseFrameRange("1-100x2").back(), 99);
}

TEST(FrameRange, BadSyntaxNamesTheItem) {
    auto message = [](const char* text) {
        try {
            parseFrameRange(text);
        } catch (const Error& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_NE(message("1-x").find("'1-x'"), std::string::npos);
    EXPECT_NE(message("3,,4").find("empty item"), std::string::npos);
    EXPECT_NE(message("10-1").find("before its start"), std::string::npos);
    EXPECT_NE(message("1-10x0").find("step must be positive"), std::string::npos);
    EXPECT_NE(message("1-10y2").find("unexpected 'y2'"), std::string::npos);
    EXPECT_NE(message("").find("empty item"), std::string::npos);
    EXPECT_NE(message("1-99999999999").find("more than"), std::string::npos);
}
