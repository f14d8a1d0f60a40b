#include "kestrel/FramePattern.h"

#include <algorithm>
#include <charconv>
#include <cstdio>

#include "kestrel/Error.h"

namespace kestrel {

namespace fs = std::filesystem;

namespace {
constexpr int kMaxDigits = 20;
// A frame list longer than this is a typo (1-1000000000), not a sequence.
constexpr size_t kMaxFrames = 10'000'000;

[[noreturn]] void badPattern(std::string_view pattern, const std::string& why) {
    throw Error("frame pattern '" + std::string(pattern) + "': " + why +
                " (expected e.g. frame.####.exr, frame.#.exr, frame.@@@.exr, frame.%04d.exr or "
                "frame_%d.exr)");
}
}  // namespace

FramePattern::FramePattern(std::string_view pattern) : pattern_(pattern) {
    std::string* out = &prefix_;
    auto takeToken = [&](int width, size_t at) {
        if (hasToken_)
            badPattern(pattern, "a second frame token at character " + std::to_string(at + 1));
        hasToken_ = true;
        width_ = width;
        out = &suffix_;
    };
    for (size_t i = 0; i < pattern.size();) {
        char c = pattern[i];
        if (c == '#' || c == '@') {
            size_t j = i;
            while (j < pattern.size() && pattern[j] == c) ++j;
            int run = int(j - i);
            // oiiotool: a lone '#' stands for 4 digits; '@' is always one digit.
            int width = (c == '#' && run == 1) ? 4 : run;
            if (width > kMaxDigits) badPattern(pattern, "more than 20 digits");
            takeToken(width, i);
            i = j;
        } else if (c == '%') {
            if (i + 1 < pattern.size() && pattern[i + 1] == '%') {
                *out += '%';
                i += 2;
                continue;
            }
            size_t j = i + 1;
            int width = 0;
            if (j < pattern.size() && pattern[j] == '0') {
                ++j;
                size_t d0 = j;
                while (j < pattern.size() && pattern[j] >= '0' && pattern[j] <= '9') ++j;
                if (j == d0) badPattern(pattern, "'%0' needs a width, as in %04d");
                auto [p, ec] = std::from_chars(pattern.data() + d0, pattern.data() + j, width);
                (void)p;
                if (ec != std::errc() || width > kMaxDigits) badPattern(pattern, "width too large");
            }
            if (j >= pattern.size() || pattern[j] != 'd')
                badPattern(pattern, "unsupported printf conversion at character " +
                                        std::to_string(i + 1) + " (only %d and %0Nd)");
            takeToken(width, i);
            i = j + 1;
        } else {
            *out += c;
            ++i;
        }
    }
}

std::string FramePattern::expand(int64_t frame) const {
    if (!hasToken_) return prefix_;
    char digits[48];
    std::snprintf(digits, sizeof digits, "%0*lld", width_, static_cast<long long>(frame));
    return prefix_ + digits + suffix_;
}

std::optional<int64_t> FramePattern::match(std::string_view path) const {
    if (!hasToken_) return std::nullopt;
    if (path.size() <= prefix_.size() + suffix_.size()) return std::nullopt;
    if (path.substr(0, prefix_.size()) != prefix_) return std::nullopt;
    if (path.substr(path.size() - suffix_.size()) != suffix_) return std::nullopt;
    std::string_view mid =
        path.substr(prefix_.size(), path.size() - prefix_.size() - suffix_.size());
    long long value = 0;
    auto [p, ec] = std::from_chars(mid.data(), mid.data() + mid.size(), value);
    if (ec != std::errc() || p != mid.data() + mid.size()) return std::nullopt;
    // Only the canonical spelling matches: the padding must be exactly what expand() writes.
    if (expand(value) != path) return std::nullopt;
    return int64_t(value);
}

std::vector<int64_t> FramePattern::findFrames() const {
    std::vector<int64_t> frames;
    if (!hasToken_ || suffix_.find('/') != std::string::npos) return frames;
    size_t slash = prefix_.rfind('/');
    std::string dirPart = slash == std::string::npos ? std::string() : prefix_.substr(0, slash + 1);
    fs::path dir = dirPart.empty() ? fs::path(".") : fs::path(dirPart);
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        std::error_code fec;
        if (it->is_directory(fec)) continue;
        if (auto f = match(dirPart + it->path().filename().string())) frames.push_back(*f);
    }
    std::sort(frames.begin(), frames.end());
    return frames;
}

std::string expandFramePattern(std::string_view pattern, int64_t frame) {
    return FramePattern(pattern).expand(frame);
}

std::vector<int64_t> findFrames(std::string_view pattern) {
    return FramePattern(pattern).findFrames();
}

std::vector<int64_t> parseFrameRange(std::string_view text) {
    auto bad = [&](std::string_view item, const std::string& why) {
        return Error("frame range '" + std::string(text) + "': " + why + " in '" +
                     std::string(item) + "' (expected e.g. 7, 1-100, 1-100x2 or 3,4,10-20x2)");
    };
    std::vector<int64_t> frames;
    size_t start = 0;
    while (true) {
        size_t comma = text.find(',', start);
        std::string_view item = text.substr(
            start, comma == std::string_view::npos ? std::string_view::npos : comma - start);
        while (!item.empty() && item.front() == ' ') item.remove_prefix(1);
        while (!item.empty() && item.back() == ' ') item.remove_suffix(1);
        if (item.empty()) throw bad(item, "empty item");
        const char* p = item.data();
        const char* end = item.data() + item.size();
        auto number = [&](long long& v, const char* what) {
            auto [q, ec] = std::from_chars(p, end, v);
            if (ec == std::errc::result_out_of_range)
                throw bad(item, std::string(what) + " too large");
            if (ec != std::errc()) throw bad(item, std::string("expected ") + what);
            p = q;
        };
        long long a = 0, b = 0, step = 1;
        number(a, "a frame number");
        b = a;
        if (p < end && *p == '-') {
            ++p;
            number(b, "a range end");
            if (p < end && *p == 'x') {
                ++p;
                number(step, "a step");
                if (step <= 0) throw bad(item, "step must be positive");
            }
            if (b < a) throw bad(item, "range end before its start");
        }
        if (p != end) throw bad(item, "unexpected '" + std::string(p, end) + "'");
        size_t count =
            size_t((static_cast<unsigned long long>(b) - static_cast<unsigned long long>(a)) /
                   static_cast<unsigned long long>(step)) +
            1;
        if (count > kMaxFrames || frames.size() + count > kMaxFrames)
            throw bad(item, "more than 10000000 frames");
        for (long long f = a; f <= b; f += step) {
            frames.push_back(f);
            if (b - f < step) break;  // no overflow past b near LLONG_MAX
        }
        if (comma == std::string_view::npos) break;
        start = comma + 1;
    }
    return frames;
}

}  // namespace kestrel
