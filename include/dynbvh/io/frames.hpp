// SPDX-License-Identifier: MIT
/// @file io/frames.hpp
/// Animated scenes made of one PLY or OBJ file per frame, and single meshes as 1-frame scenes.
///
/// A frame spec is
///  - a directory: every regular .ply / .obj file in it (case-insensitive extension), in
///    natural order (digit runs compare as numbers: f2 < f10);
///  - a printf-style pattern with one %d / %i / %u conversion, optionally zero-padded and with a
///    width (`cloth_%03d.ply`, `/data/unc/cloth_ball%d.ply`): the frames are the contiguous run of
///    indices starting at the smallest index whose file exists (a name must print back exactly:
///    `%d` does not match `cloth_ball092.ply`); `%%` is a literal percent sign;
///  - a single .ply / .obj file: a 1-frame scene (open_mesh_scene).
///
/// Frames are loaded ahead on a background thread into a bounded queue (FramesConfig::prefetch
/// frames after the last one asked for), so that Scene::frame(i, out) returns at once when frames
/// are read in order and loading never counts as build time. Random access works too (it waits
/// for that frame). Destroying the scene stops the thread after the file it is reading.
///
/// SceneInfo: name from the pattern (text before the number, trailing '_', '-', '.' removed) or
/// the directory's name; frames = the number of files; motion = FramesConfig::motion (the files
/// cannot say; default incoherent); topology_changes = whether the first and last frame differ in
/// triangle count or indices (the frames in between are not inspected); materials = those of the
/// first frame (OBJ). Each frame has one ObjectInstance covering all triangles, Frame::time =
/// i / fps, and the camera frame_bounds_camera(bounds of the first frame) in every frame.
#pragma once

#include <algorithm>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include "obj.hpp"
#include "ply.hpp"
#include "scene.hpp"

namespace dynbvh::io {

/// Options of open_frames (defaults in the comments).
struct FramesConfig {
    std::size_t prefetch = 2;            ///< frames loaded ahead in the background; 0: load in frame() on the caller's thread
    double fps = 30;                     ///< Frame::time = i / fps (the files carry no timing)
    Motion motion = Motion::incoherent;  ///< reported in SceneInfo (the files cannot say)
};

/// Reads one mesh file, chosen by extension: .ply (read_ply) or .obj (read_obj). The readers'
/// warnings are appended to `*warnings` when it is not null. A directory is an error saying so
/// (open_frames reads a directory of frames).
Mesh read_mesh(const std::string& path, std::string* warnings = nullptr);

/// The files `spec` names (see the file comment), in frame order. Throws LoadError(spec, ...)
/// when it names no frame.
std::vector<std::string> list_frames(const std::string& spec);

/// Opens a frame sequence (directory, pattern or single file). Reads the first and last frame
/// before returning (bounds, camera, materials, topology); the rest load in the background.
std::unique_ptr<Scene> open_frames(const std::string& spec, const FramesConfig& cfg = {});

/// A single PLY/OBJ file as a 1-frame scene (Motion::none).
std::unique_ptr<Scene> open_mesh_scene(const std::string& path);

// ---------------------------------------------------------------------------------------
// Implementation
// ---------------------------------------------------------------------------------------

namespace detail::frames {

inline std::string lower(std::string s) {
    for (auto& c : s) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
    return s;
}
inline bool is_mesh_file(const std::filesystem::path& p) {
    const std::string e = lower(p.extension().string());
    return e == ".ply" || e == ".obj";
}
inline bool is_digit(char c) noexcept { return c >= '0' && c <= '9'; }

/// Natural order: runs of digits compare by value, everything else by character; between
/// names equal in that sense, fewer leading zeros (at the first place they differ) come first.
inline bool natural_less(const std::string& a, const std::string& b) {
    std::size_t i = 0, j = 0;
    int zeros = 0;  // -1: a has fewer leading zeros at the first differing run, +1: b has
    while (i < a.size() && j < b.size()) {
        if (is_digit(a[i]) && is_digit(b[j])) {
            std::size_t i0 = i, j0 = j;
            while (i0 < a.size() && a[i0] == '0') ++i0;  // ignore leading zeros
            while (j0 < b.size() && b[j0] == '0') ++j0;
            std::size_t i1 = i0, j1 = j0;
            while (i1 < a.size() && is_digit(a[i1])) ++i1;
            while (j1 < b.size() && is_digit(b[j1])) ++j1;
            if (i1 - i0 != j1 - j0) return i1 - i0 < j1 - j0;
            const int c = a.compare(i0, i1 - i0, b, j0, j1 - j0);
            if (c != 0) return c < 0;
            if (zeros == 0 && i0 - i != j0 - j) zeros = i0 - i < j0 - j ? -1 : 1;
            i = i1;
            j = j1;
            continue;
        }
        if (a[i] != b[j]) return a[i] < b[j];
        ++i;
        ++j;
    }
    if (a.size() - i != b.size() - j) return a.size() - i < b.size() - j;
    return zeros < 0;
}

/// One printf conversion in a file name: prefix, %[0][width]d, suffix.
struct Pattern {
    std::string prefix, suffix;
    bool zero = false;
    std::size_t width = 0;

    std::string format(std::uint64_t n) const {
        std::string digits = std::to_string(n);
        if (digits.size() < width) digits.insert(0, width - digits.size(), zero ? '0' : ' ');
        return prefix + digits + suffix;
    }
};

/// Parses `name` (a file name, no directory); false when it has no conversion.
inline bool parse_pattern(const std::string& name, Pattern& p, const std::string& spec) {
    bool found = false;
    std::string* out = &p.prefix;
    for (std::size_t i = 0; i < name.size(); ++i) {
        if (name[i] != '%') { *out += name[i]; continue; }
        if (i + 1 < name.size() && name[i + 1] == '%') { *out += '%'; ++i; continue; }
        if (found) throw LoadError(spec, "", "a frame pattern must contain exactly one %d conversion");
        std::size_t k = i + 1;
        if (k < name.size() && name[k] == '0') { p.zero = true; ++k; }
        while (k < name.size() && is_digit(name[k])) p.width = p.width * 10 + static_cast<std::size_t>(name[k++] - '0');
        if (k >= name.size() || (name[k] != 'd' && name[k] != 'i' && name[k] != 'u') || p.width > 20)
            throw LoadError(spec, "", "unsupported conversion in frame pattern (use %d, %0Nd or %Nd)");
        found = true;
        out = &p.suffix;
        i = k;
    }
    return found;
}

inline std::string trim_name(std::string s) {
    while (!s.empty() && (s.back() == '_' || s.back() == '-' || s.back() == '.' || s.back() == ' ')) s.pop_back();
    return s;
}

/// Name of a spec for SceneInfo.
inline std::string scene_name(const std::string& spec) {
    namespace fs = std::filesystem;
    std::error_code ec;
    fs::path p(spec);
    if (fs::is_directory(p, ec)) {
        std::string n = (p.has_filename() ? p : p.parent_path()).filename().string();
        return n.empty() ? "frames" : n;
    }
    Pattern pat;
    const std::string file = p.filename().string();
    std::string n = parse_pattern(file, pat, spec) ? trim_name(pat.prefix) : p.stem().string();
    return n.empty() ? "frames" : n;
}

inline void to_frame(const Mesh& m, Frame& out, const std::string& object_name, bool animated, const Camera& cam, double time) {
    out.triangles.resize(m.faces.size());
    for (std::size_t i = 0; i < m.faces.size(); ++i)
        out.triangles[i] = {m.vertices[m.faces[i][0]], m.vertices[m.faces[i][1]], m.vertices[m.faces[i][2]]};
    out.material.assign(m.face_material.begin(), m.face_material.end());
    out.objects.resize(1);
    out.objects[0].name = object_name;
    out.objects[0].first_triangle = 0;
    out.objects[0].triangle_count = static_cast<std::uint32_t>(m.faces.size());
    out.objects[0].transform = Transform{};
    out.objects[0].animated = animated;
    out.camera = cam;
    out.time = time;
}

} // namespace detail::frames

/// One mesh file as a 1-frame scene.
class MeshScene final : public Scene {
public:
    /// Reads `path` with read_mesh (throws LoadError as it does).
    explicit MeshScene(const std::string& path) {
        Mesh m = read_mesh(path);
        info_.name = std::filesystem::path(path).stem().string();
        info_.motion = Motion::none;
        info_.frames = 1;
        info_.materials = m.materials;
        detail::frames::to_frame(m, frame_, info_.name, false, frame_bounds_camera(m.bounds()), 0);
    }
    /// Name (the file's stem), 1 frame, Motion::none, the file's materials.
    const SceneInfo& info() const override { return info_; }
    void frame(std::size_t i, Frame& out) override {
        if (i != 0) throw std::out_of_range("dynbvh::io::MeshScene::frame: frame " + std::to_string(i) + " of 1");
        out = frame_;  // copy assignment reuses out's capacity
    }

private:
    SceneInfo info_;
    Frame frame_;
};

/// A sequence of mesh files, one per frame, loaded ahead on a background thread.
class FrameSequence final : public Scene {
public:
    /// The frames `files`, in this order, as scene `name`. Reads the first and the last file at once (throws
    /// LoadError for them, std::invalid_argument for no files) and starts the loader thread when `cfg.prefetch > 0`.
    FrameSequence(std::vector<std::string> files, std::string name, const FramesConfig& cfg)
        : files_(std::move(files)), cfg_(cfg) {
        if (files_.empty()) throw std::invalid_argument("dynbvh::io::FrameSequence: no files");
        if (!(cfg_.fps > 0)) cfg_.fps = 30;
        const Mesh first = read_mesh(files_.front());
        camera_ = frame_bounds_camera(first.bounds());
        info_.name = std::move(name);
        info_.motion = cfg_.motion;
        info_.frames = files_.size();
        info_.materials = first.materials;
        if (files_.size() > 1) {
            const Mesh last = read_mesh(files_.back());
            info_.topology_changes = last.faces != first.faces;
        }
        Slot s{0, {}, {}};
        load_frame(first, 0, s.frame);
        ready_.push_back(std::move(s));
        if (cfg_.prefetch > 0 && files_.size() > 1) {
            try {
                thread_ = std::thread([this] { worker(); });
            } catch (const std::system_error&) {  // no threads: load on demand instead
            }
        }
    }
    FrameSequence(const FrameSequence&) = delete;
    FrameSequence& operator=(const FrameSequence&) = delete;
    /// Stops the loader (after the file it is reading) and joins it.
    ~FrameSequence() override {
        {
            std::lock_guard lk(mu_);
            stop_ = true;
        }
        cv_.notify_all();
        if (thread_.joinable()) thread_.join();
    }

    /// Name, frame count, motion, topology_changes and materials (see the file comment).
    const SceneInfo& info() const override { return info_; }
    /// The file of each frame.
    const std::vector<std::string>& files() const noexcept { return files_; }

    void frame(std::size_t i, Frame& out) override {
        if (i >= files_.size())
            throw std::out_of_range("dynbvh::io::FrameSequence::frame: frame " + std::to_string(i) + " of " + std::to_string(files_.size()));
        std::unique_lock lk(mu_);
        set_window(i);
        auto it = find(i);
        if (it == ready_.end()) {
            if (!thread_.joinable()) {  // synchronous mode
                lk.unlock();
                load_frame(read_mesh(files_[i]), i, out);
                lk.lock();
                set_window(i + 1);
                return;
            }
            cv_.notify_all();
            cv_.wait(lk, [&] { it = find(i); return it != ready_.end(); });
        }
        Slot s = std::move(*it);
        ready_.erase(it);
        set_window(i + 1);
        if (s.error) {
            recycle(std::move(s.frame));
            cv_.notify_all();
            std::rethrow_exception(s.error);
        }
        std::swap(out, s.frame);
        recycle(std::move(s.frame));  // out's old buffers serve a later frame
        cv_.notify_all();
    }

private:
    struct Slot {
        std::size_t index;
        Frame frame;
        std::exception_ptr error;
    };

    std::size_t depth() const noexcept { return std::max<std::size_t>(1, cfg_.prefetch); }

    void load_frame(const Mesh& m, std::size_t i, Frame& out) const {
        detail::frames::to_frame(m, out, info_.name, files_.size() > 1, camera_, static_cast<double>(i) / cfg_.fps);
    }

    std::vector<Slot>::iterator find(std::size_t i) {
        return std::find_if(ready_.begin(), ready_.end(), [i](const Slot& s) { return s.index == i; });
    }
    void recycle(Frame&& f) {
        if (spare_.size() < depth()) spare_.push_back(std::move(f));
    }
    /// The consumer wants frame `first` next: keep [first, first + depth) and drop the rest. Lock held.
    void set_window(std::size_t first) {
        window_ = first;
        for (std::size_t k = ready_.size(); k-- > 0;)
            if (ready_[k].index < window_ || ready_[k].index >= window_ + depth()) {
                recycle(std::move(ready_[k].frame));
                ready_.erase(ready_.begin() + static_cast<std::ptrdiff_t>(k));
            }
    }
    /// Smallest frame in the window that is neither ready nor being loaded, or npos. Lock held.
    std::size_t next_to_load() {
        const std::size_t end = std::min(files_.size(), window_ + depth());
        for (std::size_t j = window_; j < end; ++j)
            if (j != loading_ && find(j) == ready_.end()) return j;
        return npos;
    }

    void worker() {
        std::unique_lock lk(mu_);
        for (;;) {
            cv_.wait(lk, [&] { return stop_ || next_to_load() != npos; });
            if (stop_) return;
            const std::size_t i = next_to_load();
            loading_ = i;
            Frame f;
            if (!spare_.empty()) {
                f = std::move(spare_.back());
                spare_.pop_back();
            }
            lk.unlock();
            std::exception_ptr error;
            try {
                load_frame(read_mesh(files_[i]), i, f);
            } catch (...) {
                error = std::current_exception();
            }
            lk.lock();
            loading_ = npos;
            if (i >= window_ && i < window_ + depth()) ready_.push_back({i, std::move(f), error});
            else recycle(std::move(f));
            cv_.notify_all();
        }
    }

    static constexpr std::size_t npos = static_cast<std::size_t>(-1);
    std::vector<std::string> files_;
    FramesConfig cfg_;
    SceneInfo info_;
    Camera camera_;

    std::mutex mu_;
    std::condition_variable cv_;
    std::vector<Slot> ready_;   ///< loaded frames, all inside the window
    std::vector<Frame> spare_;  ///< buffers to reuse
    std::size_t window_ = 0;    ///< the frame the consumer wants next
    std::size_t loading_ = npos;
    bool stop_ = false;
    std::thread thread_;  ///< last member: started after everything else is ready
};

inline Mesh read_mesh(const std::string& path, std::string* warnings) {
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec))
        throw LoadError(path, "", "is a directory, not a mesh file (open_frames reads a directory of frames)");
    const std::string ext = detail::frames::lower(std::filesystem::path(path).extension().string());
    if (ext == ".ply") return read_ply(path, warnings);
    if (ext == ".obj") return read_obj(path, warnings);
    throw LoadError(path, "", "unknown mesh format '" + ext + "' (expected .ply or .obj)");
}

inline std::vector<std::string> list_frames(const std::string& spec) {
    namespace fs = std::filesystem;
    using namespace detail::frames;
    std::error_code ec;
    const fs::path p(spec);
    std::vector<std::string> files;
    if (fs::is_directory(p, ec)) {
        for (const auto& e : fs::directory_iterator(p, ec))
            if (e.is_regular_file(ec) && is_mesh_file(e.path())) files.push_back(e.path().string());
        if (ec) throw LoadError(spec, "", "cannot list the directory: " + ec.message());
        std::sort(files.begin(), files.end(), [](const std::string& a, const std::string& b) {
            return natural_less(fs::path(a).filename().string(), fs::path(b).filename().string());
        });
        if (files.empty()) throw LoadError(spec, "", "no .ply or .obj files in the directory");
        return files;
    }
    Pattern pat;
    if (!parse_pattern(p.filename().string(), pat, spec)) {
        if (!fs::is_regular_file(p, ec)) throw LoadError(spec, "", "no such file, directory or frame pattern");
        return {spec};
    }
    const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
    std::vector<std::pair<std::uint64_t, std::string>> found;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
        const std::string name = e.path().filename().string();
        if (name.size() <= pat.prefix.size() + pat.suffix.size() || name.compare(0, pat.prefix.size(), pat.prefix) != 0 ||
            name.compare(name.size() - pat.suffix.size(), pat.suffix.size(), pat.suffix) != 0)
            continue;
        const std::string mid = name.substr(pat.prefix.size(), name.size() - pat.prefix.size() - pat.suffix.size());
        const std::size_t lead = mid.find_first_not_of(' ');
        if (lead == std::string::npos || mid.size() - lead > 18 ||
            !std::all_of(mid.begin() + static_cast<std::ptrdiff_t>(lead), mid.end(), is_digit))
            continue;
        const std::uint64_t n = std::stoull(mid.substr(lead));
        if (pat.format(n) != name || !e.is_regular_file(ec)) continue;
        found.emplace_back(n, e.path().string());
    }
    if (ec) throw LoadError(spec, "", "cannot list " + dir.string() + ": " + ec.message());
    if (found.empty()) throw LoadError(spec, "", "no file matches the frame pattern");
    std::sort(found.begin(), found.end());
    for (std::size_t k = 0; k < found.size() && found[k].first == found[0].first + k; ++k) files.push_back(found[k].second);
    return files;
}

inline std::unique_ptr<Scene> open_frames(const std::string& spec, const FramesConfig& cfg) {
    auto files = list_frames(spec);
    std::error_code ec;
    if (files.size() == 1 && std::filesystem::is_regular_file(spec, ec)) return open_mesh_scene(spec);
    return std::make_unique<FrameSequence>(std::move(files), detail::frames::scene_name(spec), cfg);
}

inline std::unique_ptr<Scene> open_mesh_scene(const std::string& path) { return std::make_unique<MeshScene>(path); }

} // namespace dynbvh::io
