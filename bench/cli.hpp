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

} // namespace dynbvh::cli
