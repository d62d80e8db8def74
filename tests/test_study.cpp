// The study executable on a tiny scene, end to end: the JSON has every scene x builder x resolution,
// FPS is frames / (build + trace) of its own per-frame data, the SAH of a hand-computed 2-triangle
// tree is exact, the renders are not empty, and bad input fails with a message naming it.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdlib>
#include <sys/wait.h>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <set>
#include <string>
#include <vector>

#if defined(DYNBVH_STUDY_EXE)

#include <nlohmann/json.hpp>

namespace {

using Json = nlohmann::json;

std::string read_all(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

/// Runs dynbvh-study with `args`; stdout and stderr go to `log`. Returns the exit status.
int run_study(const std::string& args, const std::filesystem::path& log) {
    const std::string cmd = std::string("\"") + DYNBVH_STUDY_EXE + "\" " + args + " > \"" + log.string() + "\" 2>&1";
    const int rc = std::system(cmd.c_str());
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

const std::filesystem::path tmp = DYNBVH_STUDY_TMP;

} // namespace

TEST_CASE("study: tiny cloth-ball run has every group, consistent FPS and non-empty renders") {
    const auto out = tmp / "tiny";
    std::filesystem::remove_all(out);
    std::filesystem::create_directories(out);
    const int rc = run_study("--scenes cloth-ball --scale 0.02 --frames 2 --builders lbvh,ploc --res 64x48,32x24 --images 2 "
                             "--threads 2 --out \"" + out.string() + "\"",
                             out / "log.txt");
    INFO(read_all(out / "log.txt"));
    REQUIRE(rc == 0);
    const std::string text = read_all(out / "study.json");
    const Json j = Json::parse(text);

    CHECK(j.at("threads").get<double>() >= 1);
    CHECK(!j.at("machine").at("cpu").get<std::string>().empty());
    CHECK(!j.at("compiler").get<std::string>().empty());
    CHECK(!j.at("date").get<std::string>().empty());
    // What was asked for, as written back.
    CHECK(j.at("format") == "dynbvh-study 1");
    CHECK(j.at("threads") == 2);
    CHECK((j.at("embree").is_null() || j.at("embree").is_string()));
    const auto& opts = j.at("options");
    CHECK(opts.at("command_line").get<std::string>().find("--threads 2") != std::string::npos);
    CHECK(opts.at("resolutions") == Json::array({"64x48", "32x24"}));
    CHECK(opts.at("frames") == 2);
    CHECK(opts.at("scale") == 0.02);
    CHECK(opts.at("reps") == 1);
    CHECK(opts.at("effects") == "primary");
    CHECK(j.at("builders") == Json::array({"lbvh", "ploc"}));
    REQUIRE(j.at("scenes").size() == 1);
    const auto& scene = j.at("scenes").at(0);
    CHECK(scene.at("name") == "cloth-ball");
    CHECK(scene.at("kind") == "builtin");
    REQUIRE(scene.at("frames_used").size() == 2);
    CHECK(scene.at("triangles_min").get<double>() > 100);
    CHECK(j.at("sweep").is_null());

    const auto& results = j.at("results");
    REQUIRE(results.size() == 4);   // 1 scene x 2 builders x 2 resolutions
    for (const char* b : {"lbvh", "ploc"})
        for (int w : {64, 32}) {
            int found = 0;
            for (const auto& g : results)
                if (g.at("scene") == "cloth-ball" && g.at("builder") == b && g.at("width") == w) ++found;
            CHECK_MESSAGE(found == 1, b << " at width " << w);
        }
    std::size_t records = 0;
    for (const auto& g : results) {
        const auto& frames = g.at("per_frame");
        REQUIRE(frames.size() == 2);
        CHECK(g.at("frames") == 2);
        CHECK(g.at("reps") == 1);
        CHECK(g.at("effects").is_null());
        for (std::size_t k = 0; k < 2; ++k) {
            CHECK(frames.at(k).at("frame") == scene.at("frames_used").at(k));
            CHECK(frames.at(k).at("rep") == 0);
            CHECK(frames.at(k).at("triangles").get<double>() >= scene.at("triangles_min").get<double>());
            CHECK(frames.at(k).at("triangles").get<double>() <= scene.at("triangles_max").get<double>());
        }
        records += frames.size();
        double build = 0, trace = 0, sah = 0;
        for (const auto& f : frames) {
            CHECK(f.at("build_ms").get<double>() >= 0);
            CHECK(f.at("trace_ms").get<double>() > 0);
            CHECK(f.at("triangles").get<double>() > 100);
            CHECK(f.at("hits").get<double>() > 0);
            CHECK(f.at("hits").get<double>() < g.at("rays_per_frame").get<double>());
            build += f.at("build_ms").get<double>();
            trace += f.at("trace_ms").get<double>();
            sah += f.at("sah").get<double>();
        }
        CHECK(g.at("rays_per_frame").get<double>() == g.at("width").get<double>() * g.at("height").get<double>());
        CHECK(g.at("fps").get<double>() == doctest::Approx(2.0 / ((build + trace) / 1000.0)).epsilon(1e-12));
        CHECK(g.at("mean_build_ms").get<double>() == doctest::Approx(build / 2).epsilon(1e-12));
        CHECK(g.at("mean_trace_ms").get<double>() == doctest::Approx(trace / 2).epsilon(1e-12));
        CHECK(g.at("mean_sah").get<double>() == doctest::Approx(sah / 2).epsilon(1e-12));
        CHECK(g.at("mean_memory_bytes").get<double>() > 0);
    }
    // Both builders hit the same number of pixels (exact closest hits through different trees).
    for (const auto& a : results)
        for (const auto& b : results)
            if (a.at("width").get<double>() == b.at("width").get<double>())
                for (std::size_t k = 0; k < 2; ++k)
                    CHECK(a.at("per_frame").at(k).at("hits").get<double>() == b.at("per_frame").at(k).at("hits").get<double>());

    const auto& images = j.at("images");
    REQUIRE(images.size() == 2);
    for (const auto& im : images) {
        CHECK(im.at("hit_pixels").get<double>() > 0);
        CHECK(im.at("hit_pixels").get<double>() < im.at("width").get<double>() * im.at("height").get<double>());
        const std::string png = read_all(out / im.at("file").get<std::string>());
        REQUIRE(png.size() > 8);
        CHECK(png.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0);
    }
    // CSV: a header and one row per frame record.
    const std::string csv = read_all(out / "study.csv");
    std::size_t lines = 0;
    for (char c : csv) lines += c == '\n';
    CHECK(lines == records + 1);
    const std::string report = read_all(out / "report.md");
    CHECK(report.find("Table 5.2") != std::string::npos);
    CHECK(report.find("fig_build_vs_triangles.svg") != std::string::npos);
    CHECK(std::filesystem::file_size(out / "fig_build_vs_triangles.svg") > 200);
    // The crossover plot: frame time relative to the fastest builder, one line per builder.
    const std::string cross = read_all(out / "fig_crossover_cloth-ball.svg");
    CHECK(cross.find("frame time / lowest at that ray count") != std::string::npos);
    CHECK(cross.find(">lbvh</text>") != std::string::npos);
    CHECK(cross.find(">ploc</text>") != std::string::npos);
}

TEST_CASE("study: SAH of a 2-triangle scene is exact, and --info describes it") {
    const auto out = tmp / "two";
    std::filesystem::remove_all(out);
    std::filesystem::create_directories(out);
    // Two unit right triangles 100 apart in z = 0: boxes of area 2 each, root box [0,101]x[0,1]x{0} of area 202.
    // Two leaves under one root beat one leaf of two (3 * 202 + 2 * (2 + 2) < 2 * 2 * 202), so
    // SAH = (Ct * 202 + Ci * (2 * 1 + 2 * 1)) / 202 = (3 * 202 + 8) / 202.
    {
        std::ofstream ply(out / "two.ply");
        ply << "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
               "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
               "0 0 0\n1 0 0\n0 1 0\n100 0 0\n101 0 0\n100 1 0\n3 0 1 2\n3 3 4 5\n";
    }
    const double expected = (3.0 * 202.0 + 8.0) / 202.0;
    const int rc = run_study("--scenes \"" + (out / "two.ply").string() + "\" --builders lbvh:blocks=0,ploc:wide=4:blocks=0,kbvh:wide=8:blocks=0,binned-sah:blocks=0,lbvh:wide=0,ploc:wide=4:blocks=1 --res 16x16 "
                             "--images 0 --out \"" + out.string() + "\"",
                             out / "log.txt");
    INFO(read_all(out / "log.txt"));
    REQUIRE(rc == 0);
    const Json j = Json::parse(read_all(out / "study.json"));
    const auto& results = j.at("results");
    REQUIRE(results.size() == 6);
    std::set<double> default_bytes;
    for (std::size_t i = 0; i < results.size(); ++i) {
        const auto& g = results[i];
        INFO(g.at("builder").get<std::string>());
        if (i == 5) {   // (results follow the --builders order) ploc:wide=4:blocks=1
            // block leaves (Ci 0.5): one leaf of both triangles beats two (0.5 * 202 * 2 < 3 * 202 + 0.5 * 4),
            // so SAH (Ct 3, Ci 2) = 2 * 202 * 2 / 202 = 4; traced: one 4-wide node and one 4-lane block (192 bytes)
            CHECK(g.at("per_frame").at(0).at("sah").get<double>() == doctest::Approx(4.0).epsilon(1e-12));
            CHECK(g.at("per_frame").at(0).at("memory_bytes").get<double>() == 128 + 192);
            continue;
        }
        CHECK(g.at("per_frame").at(0).at("sah").get<double>() == doctest::Approx(expected).epsilon(1e-12));
        CHECK(g.at("per_frame").at(0).at("triangles").get<double>() == 2);
        // the traced tree: 3 binary nodes (32 bytes each), one 4-wide node (128 bytes) or one 8-wide node
        // (256 bytes), plus 2 references; lbvh and binned-sah trace the default width (4, or 8 with AVX)
        const std::string name = g.at("builder").get<std::string>();
        const double bytes = g.at("per_frame").at(0).at("memory_bytes").get<double>() - 2 * 4;
        if (name.find("wide=0") != std::string::npos) CHECK(bytes == 3 * 32);
        else if (name.starts_with("ploc")) CHECK(bytes == 128);
        else if (name.starts_with("kbvh")) CHECK(bytes == 256);
        else default_bytes.insert(bytes);
    }
    CHECK(default_bytes.size() == 1);
    CHECK((default_bytes.count(128) + default_bytes.count(256)) == 1);

    const int rc2 = run_study("--info \"" + (out / "two.ply").string() + "\"", out / "info.json");
    REQUIRE(rc2 == 0);
    const Json info = Json::parse(read_all(out / "info.json"));
    CHECK(info.at("triangles").get<double>() == 2);
    CHECK(info.at("frames").get<double>() == 1);
    CHECK(info.at("format").get<std::string>() == "ply");
    CHECK(info.at("bounds").at("min").at(0).get<double>() == 0);
    CHECK(info.at("bounds").at("max").at(0).get<double>() == 101);
    CHECK(info.at("bounds").at("max").at(1).get<double>() == 1);
    CHECK(info.at("topology_changes") == false);
}

TEST_CASE("study: auto (refit or rebuild) records its decisions, consistent with its SAHs, threshold and amortized costs") {
    const auto out = tmp / "auto";
    std::filesystem::remove_all(out);
    std::filesystem::create_directories(out);
    // rule=sah: th=0 rebuilds every frame; th=1e9 never rebuilds after the first frame; auto:lbvh with either
    // is then exactly lbvh rebuilt every frame, or the study's refit:lbvh (LBVH at frame 0, refitted): same SAH
    // per frame; auto:th=1e9 likewise refit (PLOC at frame 0). auto (rule=amortized) rebuilds exactly when its
    // reported loss reaches its rebuild cost.
    const int rc = run_study("--scenes n-body --scale 0.02 --frames 5 --builders lbvh,refit,refit:lbvh,ploc,auto,auto:rule=sah,"
                             "auto:th=1.05:rule=sah,auto:lbvh:th=0:rule=sah,auto:lbvh:th=1e9:rule=sah,auto:async=1:rule=sah,"
                             "auto:async=1,auto:th=1e9:rule=sah,lbvh:blocks=0,refit:blocks=0,refit:lbvh:blocks=0,"
                             "auto:lbvh:th=0:rule=sah:blocks=0,auto:lbvh:th=1e9:rule=sah:blocks=0,auto:th=1e9:rule=sah:blocks=0 "
                             "--res 32x24 --images 0 --threads 2 --no-warmup "
                             "--out \"" + out.string() + "\"",
                             out / "log.txt");
    INFO(read_all(out / "log.txt"));
    REQUIRE(rc == 0);
    const Json j = Json::parse(read_all(out / "study.json"));
    CHECK(j.at("builders") == Json::array({"lbvh", "refit", "refit:lbvh", "ploc", "auto", "auto:rule=sah", "auto:th=1.05:rule=sah",
                                           "auto:lbvh:th=0:rule=sah", "auto:lbvh:th=1e+09:rule=sah",
                                           "auto:async=1:rule=sah", "auto:async=1", "auto:th=1e+09:rule=sah", "lbvh:blocks=0",
                                           "refit:blocks=0", "refit:lbvh:blocks=0", "auto:lbvh:blocks=0:th=0:rule=sah",
                                           "auto:lbvh:blocks=0:th=1e+09:rule=sah", "auto:blocks=0:th=1e+09:rule=sah"}));
    const auto group = [&](const std::string& b) -> const Json& {
        for (const auto& g : j.at("results"))
            if (g.at("builder") == b) return g;
        FAIL("no result for " << b);
        return j;
    };
    const std::vector<std::pair<std::string, double>> autos = {
        {"auto", 1.3}, {"auto:rule=sah", 1.3}, {"auto:th=1.05:rule=sah", 1.05}, {"auto:lbvh:th=0:rule=sah", 0},
        {"auto:lbvh:th=1e+09:rule=sah", 1e9}, {"auto:async=1:rule=sah", 1.3}, {"auto:async=1", 1.3},
        {"auto:th=1e+09:rule=sah", 1e9}, {"auto:lbvh:blocks=0:th=0:rule=sah", 0}, {"auto:lbvh:blocks=0:th=1e+09:rule=sah", 1e9},
        {"auto:blocks=0:th=1e+09:rule=sah", 1e9}};
    const auto& hits_ref = group("ploc").at("per_frame");
    for (const auto& [name, th] : autos) {
        INFO(name);
        const auto& g = group(name);
        const auto& frames = g.at("per_frame");
        REQUIRE(frames.size() == 5);
        CHECK(g.at("strategy").at("threshold").get<double>() == th);
        const bool amortized = name.find("rule=sah") == std::string::npos;
        const bool async = name.find("async=1") != std::string::npos;
        CHECK(g.at("strategy").at("rule") == (amortized ? "amortized" : "sah"));
        std::size_t counted[3] = {0, 0, 0};
        for (std::size_t k = 0; k < frames.size(); ++k) {
            INFO("frame " << k);
            const auto& f = frames.at(k);
            const std::string d = f.at("decision").get<std::string>(), why = f.at("reason").get<std::string>();
            counted[0] += d == "refit";
            counted[1] += d == "rebuild";
            counted[2] += d == "swap";
            CHECK(f.at("sah_after").get<double>() == f.at("sah").get<double>());
            CHECK(f.at("hits") == hits_ref.at(k).at("hits"));   // exact closest hits through every tree
            if (k == 0) {
                CHECK(d == "rebuild");
                CHECK(why == "first_frame");
                CHECK(f.at("sah_before").is_null());
                CHECK(f.at("sah_rebuilt").get<double>() == f.at("sah").get<double>());
                continue;
            }
            if (why == "streak") {   // a run of rebuilds at every frame: rebuilt without a refit (dynamic.hpp)
                CHECK(d == "rebuild");
                CHECK(!async);
                CHECK(f.at("sah_before").is_null());
                REQUIRE(k >= 3);
                CHECK(frames.at(k - 1).at("decision") == "rebuild");
                CHECK(frames.at(k - 2).at("decision") == "rebuild");
                CHECK(f.at("sah_rebuilt").get<double>() == f.at("sah").get<double>());
                continue;
            }
            const double before = f.at("sah_before").get<double>();
            const double limit = th * frames.at(k - 1).at("sah_rebuilt").get<double>();
            const double loss = f.at("loss_ms").get<double>(), cost = f.at("rebuild_cost_ms").get<double>();
            // amortized: every frame after the first has the previous frame's trace time, so the rule applies
            if (amortized && d != "swap") CHECK(cost > 0);
            if (!amortized) CHECK(loss == 0);
            if (d == "refit") {
                // within the rule (or, async, a background rebuild is already running)
                if (why == "none" && !async) CHECK((amortized ? loss < cost : before <= limit));
                if (amortized && !async) CHECK(why == "none");
                CHECK(f.at("sah_after").get<double>() == before);
                CHECK(f.at("sah_rebuilt") == frames.at(k - 1).at("sah_rebuilt"));
            } else if (d == "rebuild") {
                CHECK(!async);   // async rebuilds in the background only
                CHECK(why == (amortized ? "amortized" : "sah_growth"));
                CHECK((amortized ? loss >= cost : before > limit));
                CHECK(f.at("sah_rebuilt").get<double>() == f.at("sah").get<double>());
            } else {
                CHECK(d == "swap");
                CHECK(async);
                CHECK(why == "rebuild_ready");
            }
        }
        CHECK(g.at("strategy").at("refit") == counted[0]);
        CHECK(g.at("strategy").at("rebuild") == counted[1]);
        CHECK(g.at("strategy").at("swap") == counted[2]);
        CHECK(counted[0] + counted[1] + counted[2] == 5);
    }
    // th=0: a rebuild every frame, the very tree lbvh builds; th=1e9: refits only, the study's refit tree.
    // Index leaves (blocks=0): the policy's binary tree is the rebuild's or refit's binary tree, same SAH.
    // Block trees (the default): the policy holds the traced block tree, the very one lbvh or refit traces
    // (same bytes; its SAH is the wide tree's, so not the binary SAH column of lbvh and refit).
    const auto at = [&](const std::string& b, std::size_t k, const char* key) { return group(b).at("per_frame").at(k).at(key); };
    for (std::size_t k = 0; k < 5; ++k) {
        INFO("frame " << k);
        for (const char* b : {"auto:lbvh:th=0:rule=sah", "auto:lbvh:blocks=0:th=0:rule=sah"}) CHECK(at(b, k, "decision") == "rebuild");
        if (k > 0)
            for (const char* b : {"auto:lbvh:th=1e+09:rule=sah", "auto:lbvh:blocks=0:th=1e+09:rule=sah", "auto:th=1e+09:rule=sah"})
                CHECK(at(b, k, "decision") == "refit");
        // (the same tree; the SAH's parallel sum may round differently from run to run)
        CHECK(at("auto:lbvh:blocks=0:th=0:rule=sah", k, "sah").get<double>() ==
              doctest::Approx(at("lbvh:blocks=0", k, "sah").get<double>()).epsilon(1e-12));
        CHECK(at("auto:lbvh:blocks=0:th=1e+09:rule=sah", k, "sah").get<double>() ==
              doctest::Approx(at("refit:lbvh:blocks=0", k, "sah").get<double>()).epsilon(1e-12));
        CHECK(at("auto:blocks=0:th=1e+09:rule=sah", k, "sah").get<double>() ==
              doctest::Approx(at("refit:blocks=0", k, "sah").get<double>()).epsilon(1e-12));
        CHECK(at("auto:lbvh:th=0:rule=sah", k, "memory_bytes") == at("lbvh", k, "memory_bytes"));
        CHECK(at("auto:lbvh:th=1e+09:rule=sah", k, "memory_bytes") == at("refit:lbvh", k, "memory_bytes"));
        CHECK(at("auto:th=1e+09:rule=sah", k, "memory_bytes") == at("refit", k, "memory_bytes"));
    }
    // Per-frame builders have no decisions.
    CHECK(group("ploc").at("strategy").is_null());
    CHECK(!group("ploc").at("per_frame").at(0).contains("decision"));
    // CSV: the decision columns, filled for strategies only.
    const std::string csv = read_all(out / "study.csv");
    const std::string header = csv.substr(0, csv.find('\n'));
    CHECK(header.ends_with(",ms_shade,decision,reason,sah_before,sah_after,sah_rebuilt,loss_ms,rebuild_cost_ms"));
    CHECK(csv.find(",auto:lbvh:th=0:rule=sah,") != std::string::npos);
    std::size_t rebuild_rows = 0, plain_rows = 0;
    for (std::size_t pos = csv.find('\n') + 1; pos < csv.size();) {
        const std::size_t end = csv.find('\n', pos);
        const std::string line = csv.substr(pos, end - pos);
        pos = end + 1;
        if (line.find(",auto") != std::string::npos) rebuild_rows += line.find(",rebuild,") != std::string::npos;
        else plain_rows += line.ends_with(",,,,,,,");
    }
    CHECK(rebuild_rows >= 2 * 5 + 9);   // auto:lbvh:th=0 (both layouts) every frame, every other strategy at frame 0
    CHECK(plain_rows == 7 * 5);   // lbvh, refit, refit:lbvh, ploc and the first three with blocks=0
    // The report: the strategies table and a frame-time-per-frame plot with every builder.
    const std::string report = read_all(out / "report.md");
    CHECK(report.find("## Strategies") != std::string::npos);
    CHECK(report.find("| n-body | auto:lbvh:th=0:rule=sah | 32x24 | 5 | 0 | 5 | 0 |") != std::string::npos);
    CHECK(report.find("fig_frames_n-body_32x24.svg") != std::string::npos);
    const std::string plot = read_all(out / "fig_frames_n-body_32x24.svg");
    for (const char* b : {">lbvh</text>", ">refit</text>", ">auto</text>", ">auto:async=1</text>"}) CHECK_MESSAGE(plot.find(b) != std::string::npos, b);
}

TEST_CASE("study: two-level runs on scenes with objects, hits like a flat tree, and is skipped with a reason elsewhere") {
    const auto out = tmp / "two_level";
    std::filesystem::remove_all(out);
    std::filesystem::create_directories(out);
    {
        std::ofstream ply(out / "one.ply");
        ply << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
               "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    }
    const int rc = run_study("--scenes n-body,cloth-ball,\"" + (out / "one.ply").string() +
                             "\" --scale 0.02 --frames 4 --builders ploc,two-level,two-level:lbvh,embree-two-level --res 32x24 --images 0 "
                             "--threads 2 --no-warmup --out \"" + out.string() + "\"",
                             out / "log.txt");
    INFO(read_all(out / "log.txt"));
    REQUIRE(rc == 0);
    const Json j = Json::parse(read_all(out / "study.json"));
    const bool embree = !j.at("embree").is_null();
    CHECK(j.at("builders") == (embree ? Json::array({"ploc", "two-level", "two-level:lbvh", "embree-two-level"})
                                      : Json::array({"ploc", "two-level", "two-level:lbvh"})));
    std::vector<std::string> variants = {"two-level", "two-level:lbvh"};
    if (embree) variants.push_back("embree-two-level");
    const auto group = [&](const std::string& scene, const std::string& b) -> const Json* {
        for (const auto& g : j.at("results"))
            if (g.at("scene") == scene && g.at("builder") == b) return &g;
        return nullptr;
    };
    for (const char* scene : {"n-body", "cloth-ball"})
        for (const std::string& b : variants) {
            INFO(scene << " " << b);
            const Json* g = group(scene, b);
            const Json* flat = group(scene, "ploc");
            REQUIRE(g != nullptr);
            REQUIRE(flat != nullptr);
            REQUIRE(g->at("per_frame").size() == 4);
            for (std::size_t k = 0; k < 4; ++k) {
                const auto& f = g->at("per_frame").at(k);
                CHECK(f.at("sah").is_null());
                if (b != "embree-two-level") CHECK(f.at("memory_bytes").get<double>() > 0);
                CHECK(f.at("triangles") == flat->at("per_frame").at(k).at("triangles"));
                // Rigid objects are their first frame's triangles taken into object space and placed again:
                // equal to the frame's triangles up to rounding, so the hit pixels agree but for a few on edges.
                const double hits = f.at("hits").get<double>(), ref = flat->at("per_frame").at(k).at("hits").get<double>();
                CHECK(hits > 0);
                CHECK(std::abs(hits - ref) <= 0.01 * 32 * 24);
            }
        }
    // The PLY has one object: two-level is skipped there, with the reason.
    bool skipped = false;
    for (const auto& sk : j.at("skipped"))
        if (sk.at("builder") == "two-level" && sk.at("scene") == "one") {
            skipped = true;
            CHECK(sk.at("reason").get<std::string>().find("object") != std::string::npos);
        }
    CHECK(skipped);
    CHECK(group("one", "two-level") == nullptr);
    CHECK(group("one", "ploc") != nullptr);
    const std::string report = read_all(out / "report.md");
    CHECK(report.find("## Two-level") != std::string::npos);
    CHECK(report.find("| n-body | two-level | 32x24 | 4 |") != std::string::npos);
    CHECK(report.find("vs embree-two-level") != std::string::npos);
    CHECK(report.find("object space") != std::string::npos);
}

TEST_CASE("study: morton-wide (blocks by default, blocks=0, wide=4) hits exactly what lbvh hits, with no SAH") {
    const auto out = tmp / "morton_wide";
    std::filesystem::remove_all(out);
    std::filesystem::create_directories(out);
    const int rc = run_study("--scenes n-body,funnel --scale 0.05 --frames 3 --builders lbvh,morton-wide,morton-wide:blocks=0,"
                             "morton-wide:wide=4:bits=63 --res 48x32 --images 0 --threads 2 --no-warmup --out \"" + out.string() + "\"",
                             out / "log.txt");
    INFO(read_all(out / "log.txt"));
    REQUIRE(rc == 0);
    const Json j = Json::parse(read_all(out / "study.json"));
    CHECK(j.at("builders") == Json::array({"lbvh", "morton-wide", "morton-wide:blocks=0", "morton-wide:bits=63:wide=4"}));
    const auto group = [&](const std::string& scene, const std::string& b) -> const Json* {
        for (const auto& g : j.at("results"))
            if (g.at("scene") == scene && g.at("builder") == b) return &g;
        return nullptr;
    };
    for (const char* scene : {"n-body", "funnel"})
        for (const char* b : {"morton-wide", "morton-wide:blocks=0", "morton-wide:bits=63:wide=4"}) {
            INFO(scene << " " << b);
            const Json* g = group(scene, b);
            const Json* ref = group(scene, "lbvh");
            REQUIRE(g != nullptr);
            REQUIRE(ref != nullptr);
            REQUIRE(g->at("per_frame").size() == 3);
            for (std::size_t k = 0; k < 3; ++k) {
                const auto& f = g->at("per_frame").at(k);
                CHECK(f.at("sah").is_null());   // no binary tree
                CHECK(f.at("memory_bytes").get<double>() > 0);
                CHECK(f.at("hits") == ref->at("per_frame").at(k).at("hits"));   // exact traversal: the same pixels hit
            }
        }
    CHECK(run_study("--builders morton-wide:wide=0 --scenes funnel --scale 0.05 --frames 1 --res 8x8 --images 0 --out \"" +
                        out.string() + "\"", out / "bad.txt") != 0);
    CHECK(read_all(out / "bad.txt").find("morton-wide builds a wide tree only") != std::string::npos);
}

TEST_CASE("study: our wide trees trace SIMD triangle blocks by default and hit exactly what index leaves hit") {
    const auto out = tmp / "blocks_default";
    std::filesystem::remove_all(out);
    std::filesystem::create_directories(out);
    const std::vector<std::string> names = {"ploc",   "ploc:blocks=0", "auto",        "auto:blocks=0", "refit",
                                            "refit:blocks=0", "ploc:wide=0", "ploc:prim=pre", "lbvh:wide=4"};
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ",") + n;
    list += ",auto:rule=sah:th=1000";   // refits every frame after the first, as refit does
    const int rc = run_study("--scenes n-body,funnel --scale 0.05 --frames 3 --builders " + list +
                             " --res 48x32 --images 0 --threads 2 --no-warmup --out \"" + out.string() + "\"",
                             out / "log.txt");
    INFO(read_all(out / "log.txt"));
    REQUIRE(rc == 0);
    const Json j = Json::parse(read_all(out / "study.json"));
    REQUIRE(j.at("builders").size() == names.size() + 1);
    for (std::size_t i = 0; i < names.size(); ++i)   // canonical names: blocks is the default, so no knob shows
        CHECK(j.at("builders").at(i) == names[i]);
    const std::string always_refit = j.at("builders").at(names.size()).get<std::string>();
    const auto group = [&](const std::string& scene, const std::string& b) -> const Json* {
        for (const auto& g : j.at("results"))
            if (g.at("scene") == scene && g.at("builder") == b) return &g;
        return nullptr;
    };
    for (const char* scene : {"n-body", "funnel"}) {
        const Json* ref = group(scene, "ploc:blocks=0");
        REQUIRE(ref != nullptr);
        for (const auto& b : names) {
            INFO(scene << " " << b);
            const Json* g = group(scene, b);
            REQUIRE(g != nullptr);
            REQUIRE(g->at("per_frame").size() == 3);
            for (std::size_t k = 0; k < 3; ++k)   // exact traversal: the same pixels hit whatever the leaves
                CHECK(g->at("per_frame").at(k).at("hits") == ref->at("per_frame").at(k).at("hits"));
        }
        // refit refits its block tree in place, the tree an always-refitting auto holds (same bytes every
        // frame), and its binary tree (the SAH column's) outside the timed build: PLOC's SAH at frame 0,
        // then refitted (the scene moves, so the SAH moves too: not stale)
        const Json* r = group(scene, "refit");
        const Json* a = group(scene, always_refit);
        REQUIRE(a != nullptr);
        for (std::size_t k = 0; k < 3; ++k) {
            INFO(scene << " frame " << k);
            CHECK(a->at("per_frame").at(k).at("decision") == (k == 0 ? "rebuild" : "refit"));
            CHECK(r->at("per_frame").at(k).at("memory_bytes") == a->at("per_frame").at(k).at("memory_bytes"));
        }
        CHECK(r->at("per_frame").at(0).at("sah").get<double>() ==
              doctest::Approx(group(scene, "ploc")->at("per_frame").at(0).at("sah").get<double>()).epsilon(1e-12));
        CHECK(r->at("per_frame").at(1).at("sah") != r->at("per_frame").at(0).at("sah"));
        CHECK(r->at("per_frame").at(2).at("sah") != r->at("per_frame").at(1).at("sah"));
        // the block trees are what is traced: their memory is the blocks', not the index leaves'
        for (const char* b : {"ploc", "auto", "refit"}) {
            INFO(scene << " " << b);
            const std::string index_leaves = std::string(b) + ":blocks=0";
            CHECK(group(scene, b)->at("per_frame").at(0).at("memory_bytes") !=
                  group(scene, index_leaves)->at("per_frame").at(0).at("memory_bytes"));
        }
    }
    CHECK(run_study("--builders two-level:blocks=1 --out \"" + out.string() + "\"", out / "bad.txt") != 0);
    CHECK(read_all(out / "bad.txt").find("two-level's objects always trace blocks") != std::string::npos);
}

TEST_CASE("study: the wide trees built directly have the SAH and hits of the same builder's binary tree") {
    // lbvh, ploc, kbvh and binned-sah build their traced wide trees directly (no binary tree converted),
    // and the SAH column then comes from the same tree's binary form built outside the timing: it must
    // equal, to the bit, the SAH of the binary tree wide=0 traces (built and timed the old way), frame by
    // frame, with the same hits.
    const auto out = tmp / "direct_wide";
    std::filesystem::remove_all(out);
    std::filesystem::create_directories(out);
    const std::vector<std::string> kinds = {"lbvh", "ploc", "kbvh", "binned-sah"};
    std::string list;
    for (const auto& k : kinds) list += (list.empty() ? "" : ",") + k + ":blocks=0," + k + ":wide=4:blocks=0," + k + ":wide=0";
    const int rc = run_study("--scenes cloth-ball,breaking --scale 0.03 --frames 3 --builders " + list +
                             " --res 40x24 --images 0 --threads 2 --no-warmup --out \"" + out.string() + "\"",
                             out / "log.txt");
    INFO(read_all(out / "log.txt"));
    REQUIRE(rc == 0);
    const Json j = Json::parse(read_all(out / "study.json"));
    const auto group = [&](const std::string& scene, const std::string& b) -> const Json& {
        for (const auto& g : j.at("results"))
            if (g.at("scene") == scene && g.at("builder") == b) return g;
        FAIL("no group " << scene << " " << b);
        throw;
    };
    for (const char* scene : {"cloth-ball", "breaking"})
        for (const auto& k : kinds) {
            const Json& binary = group(scene, k + ":wide=0");
            for (const std::string& wide : {k + ":blocks=0", k + ":wide=4:blocks=0"}) {
                const Json& g = group(scene, wide);
                REQUIRE(g.at("per_frame").size() == 3);
                for (std::size_t f = 0; f < 3; ++f) {
                    INFO(scene << " " << wide << " frame " << f);
                    const Json& a = g.at("per_frame").at(f);
                    const Json& b = binary.at("per_frame").at(f);
                    CHECK(a.at("sah").get<double>() > 1);
                    CHECK(a.at("sah").get<double>() == b.at("sah").get<double>());
                    CHECK(a.at("hits") == b.at("hits"));
                }
            }
        }
}

TEST_CASE("study: bad input fails with a message naming it") {
    const auto out = tmp / "bad";
    std::filesystem::create_directories(out);
    CHECK(run_study("--scenes no-such-scene-xyz --out \"" + out.string() + "\"", out / "log1.txt") != 0);
    CHECK(read_all(out / "log1.txt").find("no-such-scene-xyz") != std::string::npos);
    CHECK(run_study("--builders lbvh,octree --out \"" + out.string() + "\"", out / "log2.txt") != 0);
    CHECK(read_all(out / "log2.txt").find("octree") != std::string::npos);
    CHECK(run_study("--builders ploc:wide=0:blocks=1 --out \"" + out.string() + "\"", out / "log9.txt") != 0);
    CHECK(read_all(out / "log9.txt").find("blocks=1 needs a wide tree") != std::string::npos);
    CHECK(run_study("--builders auto:octree --out \"" + out.string() + "\"", out / "log5.txt") != 0);
    CHECK(read_all(out / "log5.txt").find("auto:octree") != std::string::npos);
    CHECK(run_study("--builders auto:th=-1 --out \"" + out.string() + "\"", out / "log6.txt") != 0);
    CHECK(read_all(out / "log6.txt").find("th must be") != std::string::npos);
    CHECK(run_study("--builders two-level:wide=4 --out \"" + out.string() + "\"", out / "log8.txt") != 0);
    CHECK(read_all(out / "log8.txt").find("wide") != std::string::npos);
    CHECK(run_study("--builders refit:lbvh:r=8 --out \"" + out.string() + "\"", out / "log10.txt") != 0);
    CHECK(read_all(out / "log10.txt").find("no knob 'r'") != std::string::npos);
    CHECK(run_study("--builders ploc:th=2 --out \"" + out.string() + "\"", out / "log7.txt") != 0);
    CHECK(read_all(out / "log7.txt").find("th") != std::string::npos);
    CHECK(run_study("--res 640by480", out / "log3.txt") == 2);
    CHECK(read_all(out / "log3.txt").find("640by480") != std::string::npos);
    {
        std::ofstream bad(out / "broken.ply");
        bad << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n";
    }
    CHECK(run_study("--info \"" + (out / "broken.ply").string() + "\"", out / "log4.txt") != 0);
    CHECK(read_all(out / "log4.txt").find("broken.ply") != std::string::npos);
}

TEST_CASE("study: one option syntax (--x v and --x=v), --help exits 0, bad values exit 2 naming them") {
    const auto out = tmp / "cli";
    std::filesystem::create_directories(out);
    {
        std::ofstream ply(out / "one.ply");
        ply << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
               "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    }
    const std::string info = "--info \"" + (out / "one.ply").string() + "\"";
    // --help: usage on stdout, every option listed, status 0.
    CHECK(run_study("--help", out / "help.txt") == 0);
    const std::string help = read_all(out / "help.txt");
    for (const char* opt : {"--scenes", "--builders", "--res", "--threads", "--backend", "--sweep-only", "--effects-depth", "--info"})
        CHECK_MESSAGE(help.find(opt) != std::string::npos, opt);
    CHECK(run_study("-h", out / "help2.txt") == 0);
    // Both syntaxes are accepted and give the value: --frames caps the frames inspected by --info.
    for (const char* frames : {"--frames 1", "--frames=1"}) {
        INFO(frames);
        REQUIRE(run_study(info + " " + frames + " --threads 2 --seed=7", out / "info.json") == 0);
        CHECK(Json::parse(read_all(out / "info.json")).at("frames_inspected") == 1);
    }
    CHECK(run_study(info + " --threads=2 --scale 0.5", out / "info.json") == 0);
    // Bad values and unknown options: status 2 and a message naming the option or the value.
    const std::vector<std::pair<std::string, std::string>> bad = {
        {"--threads=abc", "abc"},       {"--threads abc", "abc"},         {"--threads -1", "--threads"},
        {"--threads 5000", "--threads"}, {"--threads", "--threads"},      {"--frames -1", "--frames"},
        {"--frames 0", "--frames"},      {"--reps 1.5", "--reps"},        {"--scale nan", "--scale"},
        {"--scale 0", "--scale"},        {"--scale=17", "--scale"},       {"--seed=-3", "--seed"},
        {"--backend=gpu", "gpu"},        {"--effects all", "all"},        {"--no-such-option", "--no-such-option"},
        {"stray", "stray"},              {"--quick --full", "--quick"},   {"--res=640x", "640x"},
        {"--out=", "--out"},             {"--images=2k", "--images"},     {"--cache-mb 99999999999999999999999", "--cache-mb"},
    };
    for (const auto& [args, name] : bad) {
        INFO(args);
        CHECK(run_study(info + " " + args, out / "bad.txt") == 2);
        const std::string log = read_all(out / "bad.txt");
        CHECK_MESSAGE(log.find(name) != std::string::npos, log);
    }
}

#else

TEST_CASE("study: skipped") {
    MESSAGE("dynbvh-study is not part of this build (DYNBVH_BUILD_BENCH=OFF): study test skipped");
}

#endif
