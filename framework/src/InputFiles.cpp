#include "kestrel/InputFiles.h"

#include <array>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <vector>

#include "kestrel/Error.h"

namespace kestrel {

namespace fs = std::filesystem;
using nlohmann::json;

void checkRegularFile(const fs::path& path, const std::string& what, const std::string& expected) {
    std::error_code ec;
    const fs::file_status st = fs::status(path, ec);
    if (ec || !fs::exists(st))
        throw Error("cannot read " + what + " " + path.string() + ": " +
                    (ec ? ec.message() : std::string("no such file")));
    if (fs::is_directory(st))
        throw Error(what + " " + path.string() + " is a directory" +
                    (expected.empty() ? "" : " (expected " + expected + ")"));
    if (!fs::is_regular_file(st))
        throw Error(what + " " + path.string() +
                    " is not a regular file (a device, pipe or socket)" +
                    (expected.empty() ? "" : "; expected " + expected));
}

std::string readRegularFile(const fs::path& path, const std::string& what, std::uintmax_t maxBytes,
                            const std::string& expected) {
    checkRegularFile(path, what, expected);
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error("cannot read " + what + " " + path.string());
    // Read in chunks and stop past the limit, not one maxBytes buffer per file.
    std::string text;
    std::array<char, 64 * 1024> chunk;
    while (in.read(chunk.data(), std::streamsize(chunk.size())) || in.gcount() > 0) {
        text.append(chunk.data(), size_t(in.gcount()));
        if (text.size() > maxBytes)
            throw Error(what + " " + path.string() + " is larger than " + std::to_string(maxBytes) +
                        " bytes (is it the right file?)");
    }
    return text;
}

namespace {

/// A SAX pass over the text that builds nothing: it tracks the open arrays and objects (their
/// keys so far, the element being read) to name the JSON path of a problem.
class ShapeCheck : public nlohmann::json_sax<json> {
public:
    explicit ShapeCheck(const std::string& where) : where_(where) {}

    bool null() override { return value(); }
    bool boolean(bool) override { return value(); }
    bool number_integer(number_integer_t) override { return value(); }
    bool number_unsigned(number_unsigned_t) override { return value(); }
    bool number_float(number_float_t, const string_t&) override { return value(); }
    bool string(string_t&) override { return value(); }
    bool binary(binary_t&) override { return value(); }
    bool start_object(std::size_t) override { return open(true); }
    bool start_array(std::size_t) override { return open(false); }
    bool end_object() override { return close(); }
    bool end_array() override { return close(); }
    bool key(string_t& k) override {
        Level& l = stack_.back();
        l.key = k;
        if (!l.keys.insert(k).second)
            fail("duplicate key '" + k + "' at " + path() +
                 " (JSON keeps only the last; write it once)");
        return true;
    }
    // The parser reports syntax errors itself, with line and column.
    bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override {
        return false;
    }

private:
    struct Level {
        bool object;
        std::set<std::string> keys;  // objects: keys so far
        std::string key;             // objects: the member being read
        size_t index = 0;            // arrays: the element being read
    };

    bool value() {
        if (!stack_.empty() && !stack_.back().object) ++stack_.back().index;
        return true;
    }
    bool open(bool object) {
        if (stack_.size() >= size_t(kMaxJsonDepth))
            fail("arrays and objects nested deeper than " + std::to_string(kMaxJsonDepth) +
                 " levels at " + path() + " (is it the right file?)");
        stack_.push_back({object, {}, {}, 0});
        return true;
    }
    bool close() {
        stack_.pop_back();
        return value();  // the closed container was one element of its parent
    }
    /// "passes[1].params.sigmaL": the member or element read at each open level. Past a few
    /// levels only the first ones and the depth: the path of a 256-deep problem is not a line.
    std::string path() const {
        std::string p;
        constexpr size_t kShown = 8;
        for (size_t i = 0; i < stack_.size() && i < kShown; ++i) {
            const Level& l = stack_[i];
            if (l.object)
                p += (p.empty() ? "" : ".") + l.key;
            else
                p += "[" + std::to_string(l.index) + "]";
        }
        if (stack_.size() > kShown) p += "... (" + std::to_string(stack_.size()) + " levels deep)";
        return p.empty() ? "the top level" : p;
    }
    [[noreturn]] void fail(const std::string& message) const {
        throw GraphError(std::vector<Diagnostic>{{"", where_ + ": JSON " + message}});
    }

    std::string where_;
    std::vector<Level> stack_;
};

}  // namespace

void checkJsonText(const std::string& text, const std::string& where) {
    ShapeCheck check(where);
    json::sax_parse(text, &check);
}

}  // namespace kestrel
