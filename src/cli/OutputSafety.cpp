#include "OutputSafety.h"

#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <utility>

#include "kestrel/Error.h"
#include "kestrel/FramePattern.h"
#include "kestrel/Log.h"

namespace kestrel::cli {

namespace fs = std::filesystem;

namespace {

/// One file-name pattern a pass reads or writes, and where it came from ("input.path").
struct NamedPattern {
    std::string label;
    FramePattern pattern;
};

std::string stringParam(const PassNode& n, const char* key) {
    auto j = nlohmann::json::parse(n.paramsJson.empty() ? "{}" : n.paramsJson);
    if (j.contains(key) && j[key].is_string()) return j[key];
    return {};
}

bool readsFiles(const PassType& t) {
    for (const auto& p : t.desc.ports)
        if (p.kind == PortKind::Input) return false;
    return t.desc.findParam("path") != nullptr;
}
bool writesFiles(const PassType& t) {
    return t.desc.sink && t.desc.findParam("path") != nullptr;
}

void collect(const GraphDesc& g, const Registry& reg, bool outputs,
             std::vector<NamedPattern>& out) {
    for (const auto& n : g.passes) {
        const PassType* t = reg.find(n.type);
        if (!t || !(outputs ? writesFiles(*t) : readsFiles(*t))) continue;
        for (const char* key : {"path", "preview"}) {
            if (!t->desc.findParam(key)) continue;
            std::string text = stringParam(n, key);
            if (!text.empty()) out.push_back({n.name + "." + key, FramePattern(text)});
        }
    }
}

/// "out.exr" -> "out.####.exr": the fix the message suggests.
std::string withFrameToken(const std::string& pattern) {
    fs::path p(pattern);
    return (p.parent_path() / (p.stem().string() + ".####" + p.extension().string())).string();
}

void checkFrameTokens(const std::vector<NamedPattern>& outputs, size_t written) {
    if (written <= 1) return;  // a single frame may go to a plain file name
    for (const auto& o : outputs)
        if (!o.pattern.hasFrameToken())
            throw Error("output pattern '" + o.pattern.pattern() + "' (" + o.label +
                        ") has no frame number (#, @ or %04d): each of the " +
                        std::to_string(written) + " frames would overwrite the last; write e.g. " +
                        withFrameToken(o.pattern.pattern()));
}

/// `pattern` with the folders that hold the frame number left out and the number in the file
/// name: out/####/f.exr -> out/f.####.exr (the fix the message suggests).
std::string tokenInFileName(const FramePattern& pattern) {
    const fs::path a(pattern.expand(1)), b(pattern.expand(2)), p(pattern.pattern());
    fs::path folder;
    for (auto ia = a.begin(), ib = b.begin(), ip = p.begin(); ip != p.end(); ++ia, ++ib, ++ip)
        if (std::next(ip) != p.end() && *ia == *ib) folder /= *ip;
    const fs::path file = folder / p.filename();
    return a.filename() == b.filename() ? withFrameToken(file.string()) : file.string();
}

/// The frame number in a folder name (out/####/f.exr): only the first frame's folder is made
/// before the run, so frame 2 failed hours in. One rule: every frame's file in one folder.
void checkTokenInFileName(const std::vector<NamedPattern>& outputs) {
    for (const auto& o : outputs)
        if (o.pattern.hasFrameToken() && fs::path(o.pattern.expand(1)).parent_path() !=
                                             fs::path(o.pattern.expand(2)).parent_path())
            throw Error("output pattern '" + o.pattern.pattern() + "' (" + o.label +
                        ") has the frame number in a folder name: only the first frame's folder "
                        "would be created; put it in the file name, e.g. " +
                        tokenInFileName(o.pattern));
}

/// The longest name a folder takes (NAME_MAX), asked of its nearest existing ancestor.
long nameMax(fs::path dir) {
    std::error_code ec;
    while (!dir.empty() && !fs::is_directory(dir, ec)) dir = dir.parent_path();
    const long n = ::pathconf(dir.empty() ? "." : dir.c_str(), _PC_NAME_MAX);
    return n > 0 ? n : 255;
}

/// Each frame is written as `.NAME.tmp-PID` first (ExrWriter.cpp), 6 bytes and a pid (up to 10
/// digits) longer than NAME: a name within NAME_MAX but not with those failed at the write.
void checkNameLengths(const std::vector<NamedPattern>& outputs, const RunFrames& frames) {
    constexpr size_t kTemporaryExtra = 6 + 10;
    for (const auto& o : outputs)
        for (int64_t f : frames.written) {
            const fs::path file(o.pattern.expand(f));
            const size_t bytes = file.filename().string().size();
            const size_t limit = size_t(nameMax(file.parent_path()));
            if (bytes + kTemporaryExtra > limit)
                throw Error("output " + file.string() + " (" + o.label + ", frame " +
                            std::to_string(f) + "): the file name is " + std::to_string(bytes) +
                            " bytes; its temporary name (.NAME.tmp-PID, " +
                            std::to_string(kTemporaryExtra) + " bytes more) would exceed the " +
                            std::to_string(limit) + "-byte limit of a name (NAME_MAX); use at most " +
                            std::to_string(limit - kTemporaryExtra) + " bytes");
            if (!o.pattern.hasFrameToken()) break;
        }
}

/// What makes two names the same file: the resolved path (symlinks and '..' followed) and,
/// for a file that exists, its device and inode (hard links).
struct FileIdentity {
    std::string canonical;
    bool exists = false;
    std::pair<uint64_t, uint64_t> inode{};
};

fs::path resolve(const fs::path& p) {
    std::error_code ec;
    fs::path abs = fs::absolute(p, ec);
    if (ec) abs = p;
    fs::path canon = fs::weakly_canonical(abs, ec);
    return (ec ? abs : canon).lexically_normal();
}

/// Resolves names frame after frame: each folder once (a sequence shares one or two), and the
/// file itself only when it is a symlink. 1-2 system calls per file instead of one per
/// component: 100k frames in well under a second.
class Resolver {
public:
    FileIdentity identify(const std::string& name) {
        FileIdentity id;
        const fs::path p(name);
        struct stat st {};
        const bool present = ::lstat(name.c_str(), &st) == 0;
        if (present && S_ISLNK(st.st_mode))
            id.canonical = resolve(p).string();
        else
            id.canonical = (folder(p.parent_path()) / p.filename()).lexically_normal().string();
        if (present && (!S_ISLNK(st.st_mode) || ::stat(name.c_str(), &st) == 0)) {
            id.exists = true;
            id.inode = {uint64_t(st.st_dev), uint64_t(st.st_ino)};
        }
        return id;
    }

private:
    const fs::path& folder(const fs::path& dir) {
        auto it = folders_.find(dir.string());
        if (it == folders_.end())
            it = folders_.emplace(dir.string(), resolve(dir.empty() ? fs::path(".") : dir)).first;
        return it->second;
    }
    std::map<std::string, fs::path> folders_;
};

/// A file the run touches, and the parameter ("input.path") that names it.
struct InputFile {
    std::string name, label;
};

}  // namespace

/// Files by resolved name and by inode (hard links), the first label kept.
struct FilesRead::Index {
    Resolver resolver;
    std::map<std::string, InputFile> byPath;
    std::map<std::pair<uint64_t, uint64_t>, InputFile> byInode;
};

FilesRead::FilesRead() : index_(std::make_unique<Index>()) {}
FilesRead::~FilesRead() = default;

void FilesRead::add(const std::string& file, const std::string& label) {
    const FileIdentity id = index_->resolver.identify(file);
    index_->byPath.emplace(id.canonical, InputFile{file, label});
    if (id.exists) index_->byInode.emplace(id.inode, InputFile{file, label});
}

void FilesRead::addGraph(const GraphDesc& graph) {
    for (const auto& f : graph.files)
        add(f.string(), f == graph.sourcePath ? "the graph" : "a file the graph includes");
}

void FilesRead::addSources(const CompiledGraph& compiled, const std::vector<int64_t>& frames) {
    for (const auto& [name, pass] : compiled.livePasses())
        for (int64_t f : frames)
            for (const auto& [file, param] : pass->filesRead(f)) add(file, name + "." + param);
}

void FilesRead::check(const std::string& file, const std::string& label,
                      const std::string& fix) const {
    const FileIdentity id = index_->resolver.identify(file);
    const InputFile* hit = nullptr;
    if (auto it = index_->byPath.find(id.canonical); it != index_->byPath.end()) hit = &it->second;
    if (auto it = index_->byInode.find(id.inode); !hit && id.exists && it != index_->byInode.end())
        hit = &it->second;
    if (!hit) return;
    const bool sameName =
        fs::path(file).lexically_normal() == fs::path(hit->name).lexically_normal();
    throw Error("output " + file + " (" + label + ") is " +
                (sameName ? "read by this command as " + hit->label
                          : "the input " + hit->name + " (" + hit->label +
                                ") under another name (a symlink, '..' or a hard link)") +
                ": writing would destroy it; " + fix);
}

namespace {

void checkNotInputs(const std::vector<NamedPattern>& inputs,
                    const std::vector<NamedPattern>& outputs, const RunFrames& frames,
                    FilesRead& read) {
    for (const auto& o : outputs)
        for (const auto& i : inputs)
            if (o.pattern.pattern() == i.pattern.pattern())
                throw Error("output pattern '" + o.pattern.pattern() + "' (" + o.label +
                            ") is the input pattern '" + i.pattern.pattern() + "' (" + i.label +
                            "): writing would overwrite the input frames; give another --output");
    for (const auto& i : inputs)
        for (int64_t f : frames.read) {
            read.add(i.pattern.expand(f), i.label);
            if (!i.pattern.hasFrameToken()) break;
        }
    for (const auto& o : outputs)
        for (int64_t f : frames.written) {
            read.check(o.pattern.expand(f), o.label + ", frame " + std::to_string(f),
                       "give another --output");
            if (!o.pattern.hasFrameToken()) break;
        }
}

/// Two writers (or a writer's EXR and its PNG preview) on one file: the last one to finish
/// would silently replace the other's frame.
void checkOutputsDistinct(const std::vector<NamedPattern>& outputs, const RunFrames& frames,
                          Resolver& resolver) {
    std::map<std::string, InputFile> seen;  // resolved path -> first writer of it
    for (const auto& o : outputs)
        for (int64_t f : frames.written) {
            const std::string name = o.pattern.expand(f);
            auto [it, fresh] =
                seen.emplace(resolver.identify(name).canonical, InputFile{name, o.label});
            if (!fresh && it->second.label != o.label)
                throw Error("output " + name + " (" + o.label + ", frame " + std::to_string(f) +
                            ") is also written by " + it->second.label +
                            ": one would overwrite the other; give them different patterns");
            if (!o.pattern.hasFrameToken()) break;
        }
}

}  // namespace

void checkOutputsAreSafe(const GraphDesc& graph, const Registry& registry, const RunFrames& frames,
                         const std::string& reference, const CompiledGraph* compiled) {
    std::vector<NamedPattern> inputs, outputs;
    collect(graph, registry, false, inputs);
    collect(graph, registry, true, outputs);
    if (!reference.empty()) inputs.push_back({"--reference", FramePattern(reference)});
    FilesRead read;
    read.addGraph(graph);
    if (compiled) read.addSources(*compiled, frames.read);
    checkNotInputs(inputs, outputs, frames, read);  // first: losing inputs is the worse harm
    Resolver resolver;
    checkFrameTokens(outputs, frames.written.size());
    checkTokenInFileName(outputs);
    checkNameLengths(outputs, frames);
    checkOutputsDistinct(outputs, frames, resolver);
}

std::vector<std::string> outputFiles(const GraphDesc& graph, const Registry& registry,
                                     const std::vector<int64_t>& frames) {
    std::vector<NamedPattern> outputs;
    collect(graph, registry, true, outputs);
    std::vector<std::string> files;
    for (const auto& o : outputs)
        for (int64_t f : frames) {
            files.push_back(o.pattern.expand(f));
            if (!o.pattern.hasFrameToken()) break;
        }
    return files;
}

namespace {

/// The pid of ".NAME.tmp-PID" when `entry` is that temporary of NAME, else 0.
pid_t temporaryOf(const std::string& entry, const std::set<std::string>& names) {
    const auto at = entry.rfind(".tmp-");
    if (entry.size() < 2 || entry[0] != '.' || at == std::string::npos || at < 2) return 0;
    const std::string digits = entry.substr(at + 5);
    if (digits.empty() || digits.size() > 9 ||
        digits.find_first_not_of("0123456789") != std::string::npos)
        return 0;
    return names.count(entry.substr(1, at - 1)) ? pid_t(std::stol(digits)) : 0;
}

bool processRunning(pid_t pid) {
    return pid == ::getpid() || ::kill(pid, 0) == 0 || errno != ESRCH;
}

}  // namespace

int removeStaleTemporaries(const std::vector<std::string>& files, std::chrono::seconds minAge) {
    std::map<fs::path, std::set<std::string>> byFolder;
    for (const auto& f : files) {
        const fs::path p(f);
        byFolder[p.parent_path().empty() ? fs::path(".") : p.parent_path()].insert(
            p.filename().string());
    }
    int removed = 0;
    const auto now = fs::file_time_type::clock::now();
    for (const auto& [folder, names] : byFolder) {
        std::error_code ec;
        for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
            const pid_t pid = temporaryOf(it->path().filename().string(), names);
            if (pid <= 0 || processRunning(pid)) continue;
            std::error_code tec;
            const auto written = fs::last_write_time(it->path(), tec);
            if (tec || now - written < minAge) continue;
            if (fs::remove(it->path(), tec)) {
                spdlog::info("removed {}: a temporary file of process {}, which is gone",
                             it->path().string(), pid);
                ++removed;
            }
        }
    }
    return removed;
}

}  // namespace kestrel::cli
