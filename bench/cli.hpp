// One command-line convention for dynbvh's executables, on CLI11: `--x v` and `--x=v` both work,
// --help prints usage and exits 0, an unknown option or a bad value prints what is wrong and exits 2.
#pragma once

#include <charconv>
#include <cstdio>
#include <optional>
#include <string>
#include <type_traits>

#include <CLI/CLI.hpp>

namespace dynbvh::cli {

/// A validator accepting a number of type T in [lo, hi], the whole text and nothing else
/// (CLI11's own conversion lets "-1" through to unsigned options and "nan" to floating ones).
template <class T>
CLI::Validator number_in(T lo, T hi) {
    return CLI::Validator(
        [lo, hi](std::string& s) -> std::string {
            T x{};
            const char* end = s.data() + s.size();
            const auto r = std::from_chars(s.data(), end, x);
            const char* what = std::is_floating_point_v<T> ? "a number" : "a whole number";
            if (s.empty() || r.ec != std::errc() || r.ptr != end) return "'" + s + "' is not " + what;
            if (!(x >= lo && x <= hi)) {
                std::string range = std::is_floating_point_v<T> ? CLI::detail::to_string(lo) + ", " + CLI::detail::to_string(hi)
                                                                : std::to_string(lo) + ", " + std::to_string(hi);
                return "'" + s + "' is not in [" + range + "]";
            }
            return {};
        },
        "");
}

/// Every single-valued option given twice takes the last value (as the hand-written parsers did).
inline void take_last(CLI::App& app) { app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast); }

/// Parses argv into `app`. Returns nullopt to go on, else the exit status: 0 after --help (usage on
/// stdout), 2 after an error (the message and a pointer to --help on stderr).
inline std::optional<int> parse(CLI::App& app, int argc, const char* const* argv) {
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        if (e.get_exit_code() == 0) {
            std::fputs(app.help().c_str(), stdout);
            return 0;
        }
        std::fprintf(stderr, "%s: %s (see --help)\n", app.get_name().c_str(), e.what());
        return 2;
    }
    return std::nullopt;
}

/// For Google Benchmark executables: our options through CLI11, Google Benchmark's own flags
/// (--benchmark_*=V, --v=N) left in argv for benchmark::Initialize. Returns nullopt to go on (argc/argv
/// then hold the program name and the benchmark flags), else the exit status as parse() does;
/// --help lists ours and names the benchmark flags.
inline std::optional<int> parse_with_benchmark_flags(CLI::App& app, int& argc, char** argv) {
    app.allow_extras();
    app.footer("Google Benchmark's own flags pass through, e.g. --benchmark_filter=REGEX, --benchmark_min_time=SECONDS,\n"
               "--benchmark_repetitions=N, --benchmark_format=console|json|csv, --benchmark_out=FILE, --benchmark_list_tests.");
    if (const auto rc = parse(app, argc, argv)) return rc;
    int n = 1;
    for (const std::string& a : app.remaining()) {
        if (a.rfind("--benchmark_", 0) != 0 && a.rfind("--v=", 0) != 0) {
            std::fprintf(stderr, "%s: unknown option '%s' (see --help)\n", app.get_name().c_str(), a.c_str());
            return 2;
        }
        // Keep benchmark's flags: find each in argv (CLI11 hands copies back, in order).
        for (int i = n; i < argc; ++i)
            if (a == argv[i]) {
                std::swap(argv[n], argv[i]);
                ++n;
                break;
            }
    }
    argc = n;
    return std::nullopt;
}

} // namespace dynbvh::cli
