#include "progress.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <unistd.h>

namespace dynbvh::study {

std::string format_duration(double s) {
    if (!std::isfinite(s) || s < 0) return "?";
    char buf[32];
    const long t = std::lround(s);
    if (t >= 3600) std::snprintf(buf, sizeof buf, "%ldh%02ldm", t / 3600, (t / 60) % 60);
    else if (t >= 60) std::snprintf(buf, sizeof buf, "%ldm%02lds", t / 60, t % 60);
    else std::snprintf(buf, sizeof buf, "%.1fs", s);
    return buf;
}

Progress::Progress(double total)
    : total_(std::max(total, 1e-9)), tty_(isatty(STDERR_FILENO) != 0), start_(clock::now()), last_draw_(start_) {}

double Progress::elapsed_s() const { return std::chrono::duration<double>(clock::now() - start_).count(); }

void Progress::advance(double done, const std::string& what) {
    done_ = std::min(total_, done_ + done);
    draw(what, false);
}

void Progress::draw(const std::string& what, bool force) {
    const auto now = clock::now();
    const double frac = done_ / total_;
    const double el = elapsed_s();
    const double eta = frac > 0.002 ? el * (1 - frac) / frac : NAN;
    if (tty_) {
        if (!force && now - last_draw_ < std::chrono::milliseconds(100)) return;
        const int width = 30;
        const int fill = int(frac * width);
        std::string bar(std::size_t(fill), '#');
        bar.append(std::size_t(width - fill), '.');
        std::string label = what.size() > 40 ? what.substr(0, 40) : what;
        std::fprintf(stderr, "\r[%s] %5.1f%%  %s elapsed, %s left  %-40s", bar.c_str(), 100 * frac, format_duration(el).c_str(),
                     format_duration(eta).c_str(), label.c_str());
        std::fflush(stderr);
        drawn_ = true;
    } else {
        const int decile = int(frac * 10);
        if (!force && decile == last_decile_ && now - last_draw_ < std::chrono::seconds(15)) return;
        last_decile_ = decile;
        std::fprintf(stderr, "dynbvh-study: %3.0f%%, %s elapsed, ~%s left (%s)\n", 100 * frac, format_duration(el).c_str(),
                     format_duration(eta).c_str(), what.c_str());
    }
    last_draw_ = now;
}

void Progress::note(const std::string& msg) {
    if (tty_ && drawn_) std::fprintf(stderr, "\r%*s\r", 110, "");
    std::fprintf(stderr, "%s\n", msg.c_str());
    drawn_ = false;
}

void Progress::finish(const std::string& what) {
    if (tty_ && drawn_) std::fprintf(stderr, "\r%*s\r", 110, "");
    std::fprintf(stderr, "dynbvh-study: %s in %s\n", what.c_str(), format_duration(elapsed_s()).c_str());
    drawn_ = false;
}

} // namespace dynbvh::study
