// Progress on stderr: a bar with percentage and ETA redrawn in place when stderr is a terminal,
// otherwise a line every 10 % or 15 s (logs stay short).
#pragma once

#include <chrono>
#include <string>

namespace dynbvh::study {

class Progress {
public:
    /// `total` work units (any unit: the runner weighs a frame by its rays and triangles).
    explicit Progress(double total);
    /// Adds `done` units; `what` names the current step.
    void advance(double done, const std::string& what);
    /// Prints a message without breaking the bar.
    void note(const std::string& msg);
    /// Clears the bar and prints the elapsed time.
    void finish(const std::string& what);
    double elapsed_s() const;

private:
    void draw(const std::string& what, bool force);
    using clock = std::chrono::steady_clock;
    double total_, done_ = 0;
    bool tty_;
    clock::time_point start_, last_draw_;
    int last_decile_ = -1;
    bool drawn_ = false;
};

/// "1m05s", "12s", "1h02m".
std::string format_duration(double seconds);

} // namespace dynbvh::study
