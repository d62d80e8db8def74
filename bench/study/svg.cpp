#include "svg.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace dynbvh::study {

namespace {

constexpr const char* palette[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
                                   "#e377c2", "#7f7f7f", "#bcbd22", "#17becf", "#393b79", "#637939"};
const char* colour(std::size_t i) { return palette[i % (sizeof palette / sizeof palette[0])]; }

std::string esc(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c == '<') o += "&lt;";
        else if (c == '>') o += "&gt;";
        else if (c == '&') o += "&amp;";
        else if (c == '"') o += "&quot;";
        else o += c;
    }
    return o;
}

std::string num(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f", x);
    return buf;
}

std::string tick_label(double v) {
    char buf[32];
    const double a = std::abs(v);
    if (a == 0) return "0";
    if (a >= 1e9) std::snprintf(buf, sizeof buf, "%gG", v / 1e9);
    else if (a >= 1e6) std::snprintf(buf, sizeof buf, "%gM", v / 1e6);
    else if (a >= 1e4) std::snprintf(buf, sizeof buf, "%gk", v / 1e3);
    else std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

struct Axis {
    double lo = 0, hi = 1;
    bool log = false;
    double map(double v, double a, double b) const {   // value -> pixel in [a, b]
        double t;
        if (log) t = (std::log10(std::max(v, 1e-300)) - std::log10(lo)) / (std::log10(hi) - std::log10(lo));
        else t = (v - lo) / (hi - lo);
        return a + t * (b - a);
    }
    std::vector<double> ticks() const {
        std::vector<double> t;
        if (log) {
            for (double e = std::floor(std::log10(lo)); e <= std::ceil(std::log10(hi)); e += 1) {
                const double v = std::pow(10.0, e);
                if (v >= lo * 0.999 && v <= hi * 1.001) t.push_back(v);
            }
            if (t.size() < 3) {   // narrow log range: add 2x and 5x
                std::vector<double> more;
                for (double e = std::floor(std::log10(lo)); e <= std::ceil(std::log10(hi)); e += 1)
                    for (double m : {1.0, 2.0, 5.0}) {
                        const double v = m * std::pow(10.0, e);
                        if (v >= lo * 0.999 && v <= hi * 1.001) more.push_back(v);
                    }
                t = more;
            }
        } else {
            const double span = hi - lo;
            const double raw = span / 5;
            const double mag = std::pow(10.0, std::floor(std::log10(raw)));
            double step = mag;
            for (double m : {1.0, 2.0, 2.5, 5.0, 10.0})
                if (m * mag >= raw) {
                    step = m * mag;
                    break;
                }
            for (double v = std::ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) t.push_back(std::abs(v) < step * 1e-9 ? 0 : v);
        }
        return t;
    }
};

Axis make_axis(double lo, double hi, bool log, bool zero_based) {
    Axis a;
    a.log = log;
    if (!(lo <= hi) || !std::isfinite(lo) || !std::isfinite(hi)) {
        lo = log ? 1 : 0;
        hi = log ? 10 : 1;
    }
    if (log) {
        lo = std::max(lo, 1e-12);
        hi = std::max(hi, lo);
        a.lo = std::pow(10.0, std::floor(std::log10(lo)));
        a.hi = std::pow(10.0, std::ceil(std::log10(hi)));
        if (a.hi <= a.lo) a.hi = a.lo * 10;
    } else {
        if (zero_based) lo = std::min(lo, 0.0);
        if (hi == lo) hi = lo + 1;
        const double pad = (hi - lo) * 0.05;
        a.lo = zero_based && lo >= 0 ? lo : lo - pad;
        a.hi = hi + pad;
    }
    return a;
}

const double W = 760, H = 430, L = 78, R = 190, T = 40, B = 58;   // canvas and margins (legend on the right)

std::string frame_and_axes(const std::string& title, const std::string& xlabel, const std::string& ylabel, const Axis& y,
                           const Axis* x) {
    std::string s = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + num(W) + "\" height=\"" + num(H) + "\" viewBox=\"0 0 " +
                    num(W) + " " + num(H) + "\" font-family=\"sans-serif\" font-size=\"12\">\n";
    s += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    s += "<text x=\"" + num(W / 2) + "\" y=\"22\" text-anchor=\"middle\" font-size=\"14\" font-weight=\"bold\">" + esc(title) + "</text>\n";
    const double x0 = L, x1 = W - R, y0 = H - B, y1 = T;
    for (double v : y.ticks()) {
        const double py = y.map(v, y0, y1);
        s += "<line x1=\"" + num(x0) + "\" y1=\"" + num(py) + "\" x2=\"" + num(x1) + "\" y2=\"" + num(py) +
             "\" stroke=\"#e4e4e4\"/>\n";
        s += "<text x=\"" + num(x0 - 6) + "\" y=\"" + num(py + 4) + "\" text-anchor=\"end\">" + tick_label(v) + "</text>\n";
    }
    if (x) {
        for (double v : x->ticks()) {
            const double px = x->map(v, x0, x1);
            s += "<line x1=\"" + num(px) + "\" y1=\"" + num(y0) + "\" x2=\"" + num(px) + "\" y2=\"" + num(y1) +
                 "\" stroke=\"#e4e4e4\"/>\n";
            s += "<text x=\"" + num(px) + "\" y=\"" + num(y0 + 16) + "\" text-anchor=\"middle\">" + tick_label(v) + "</text>\n";
        }
    }
    s += "<rect x=\"" + num(x0) + "\" y=\"" + num(y1) + "\" width=\"" + num(x1 - x0) + "\" height=\"" + num(y0 - y1) +
         "\" fill=\"none\" stroke=\"#444\"/>\n";
    s += "<text x=\"" + num((x0 + x1) / 2) + "\" y=\"" + num(H - 14) + "\" text-anchor=\"middle\">" + esc(xlabel) + "</text>\n";
    s += "<text transform=\"translate(18," + num((y0 + y1) / 2) + ") rotate(-90)\" text-anchor=\"middle\">" + esc(ylabel) + "</text>\n";
    return s;
}

std::string legend(const std::vector<std::string>& labels, const std::vector<std::string>& colours, const std::vector<int>& style) {
    // style: 0 = box (bars), 1 = line, 2 = marker only, 3 = dashed line
    std::string s;
    const double lx = W - R + 14;
    for (std::size_t i = 0; i < labels.size(); ++i) {
        const double ly = T + 8 + 18 * double(i);
        if (style[i] == 2)
            s += "<circle cx=\"" + num(lx + 11) + "\" cy=\"" + num(ly) + "\" r=\"4\" fill=\"" + colours[i] + "\"/>\n";
        else if (style[i] == 1 || style[i] == 3)
            s += "<line x1=\"" + num(lx) + "\" y1=\"" + num(ly) + "\" x2=\"" + num(lx + 22) + "\" y2=\"" + num(ly) + "\" stroke=\"" +
                 colours[i] + "\" stroke-width=\"2.5\"" + (style[i] == 3 ? " stroke-dasharray=\"6,4\"" : "") + "/>\n";
        else
            s += "<rect x=\"" + num(lx + 4) + "\" y=\"" + num(ly - 6) + "\" width=\"14\" height=\"12\" fill=\"" + colours[i] + "\"/>\n";
        std::string l = labels[i].size() > 24 ? labels[i].substr(0, 23) + "." : labels[i];
        s += "<text x=\"" + num(lx + 28) + "\" y=\"" + num(ly + 4) + "\">" + esc(l) + "</text>\n";
    }
    return s;
}

struct PointLabel {
    double px, py;   ///< the point, in pixels
    std::string text, colour;
};

/// Labels beside their points inside the frame [x0, x1] x [y1, y0]: each goes right of its point, else
/// left, moved up or down a line at a time until it covers no marker and no label placed before it;
/// a thin line joins a moved label to its point.
std::string place_labels(const std::vector<PointLabel>& labels, double x0, double x1, double y1, double y0) {
    struct Box {
        double l, t, r, b;
        bool overlaps(const Box& o) const { return l < o.r && o.l < r && t < o.b && o.t < b; }
    };
    std::vector<Box> taken;
    for (const auto& l : labels) taken.push_back({l.px - 4, l.py - 4, l.px + 4, l.py + 4});
    std::string s;
    const double line = 11;
    for (const auto& l : labels) {
        const double w = 5.6 * double(l.text.size()) + 2;
        bool placed = false;
        for (int step = 0; step <= 12 && !placed; ++step)
            for (int sign : {-1, 1}) {
                if (placed || (step == 0 && sign == 1)) continue;
                for (bool right : {true, false}) {
                    const double x = right ? l.px + 5 : l.px - 5 - w, base = l.py - 3 + sign * step * line;
                    const Box b{x, base - 9, x + w, base + 2};
                    if (placed || b.l < x0 || b.r > x1 || b.t < y1 || b.b > y0) continue;
                    bool free = true;
                    for (const auto& o : taken) free = free && !b.overlaps(o);
                    if (!free) continue;
                    taken.push_back(b);
                    placed = true;
                    if (step > 1)
                        s += "<line x1=\"" + num(l.px) + "\" y1=\"" + num(l.py) + "\" x2=\"" + num(right ? b.l : b.r) + "\" y2=\"" +
                             num(base - 4) + "\" stroke=\"" + l.colour + "\" stroke-width=\"0.5\"/>\n";
                    s += "<text x=\"" + num(x + 1) + "\" y=\"" + num(base) + "\" font-size=\"10\" fill=\"" + l.colour + "\">" +
                         esc(l.text) + "</text>\n";
                }
            }
        if (!placed)   // crowded beyond the search: next to the point anyway
            s += "<text x=\"" + num(l.px + 5) + "\" y=\"" + num(l.py - 5) + "\" font-size=\"10\" fill=\"" + l.colour + "\">" +
                 esc(l.text) + "</text>\n";
    }
    return s;
}

} // namespace

std::string svg_line_plot(const LinePlot& p) {
    double xlo = std::numeric_limits<double>::infinity(), xhi = -xlo, ylo = xlo, yhi = -xlo;
    for (const auto& s : p.series)
        for (const auto& [x, y] : s.points) {
            if (!std::isfinite(x) || !std::isfinite(y) || (p.logx && x <= 0) || (p.logy && y <= 0)) continue;
            xlo = std::min(xlo, x);
            xhi = std::max(xhi, x);
            ylo = std::min(ylo, y);
            yhi = std::max(yhi, y);
        }
    const Axis xa = make_axis(xlo, xhi, p.logx, false);
    Axis ya = make_axis(ylo, yhi, p.logy, true);
    const bool fixed_y = !p.logy && p.ymin < p.ymax;
    if (fixed_y) ya = Axis{p.ymin, p.ymax, false};
    std::string s = frame_and_axes(p.title, p.xlabel, p.ylabel, ya, &xa);
    const double x0 = L, x1 = W - R, y0 = H - B, y1 = T;
    // Lines and markers outside a fixed y range are cut at the frame.
    if (fixed_y)
        s += "<clipPath id=\"frame\"><rect x=\"" + num(x0) + "\" y=\"" + num(y1) + "\" width=\"" + num(x1 - x0) + "\" height=\"" +
             num(y0 - y1) + "\"/></clipPath>\n<g clip-path=\"url(#frame)\">\n";
    for (const auto& [xv, label] : p.xmarks) {
        if (!(xv >= xa.lo && xv <= xa.hi)) continue;
        const double px = xa.map(xv, x0, x1);
        s += "<line x1=\"" + num(px) + "\" y1=\"" + num(y0) + "\" x2=\"" + num(px) + "\" y2=\"" + num(y1) +
             "\" stroke=\"#999\" stroke-dasharray=\"3,3\"/>\n";
        s += "<text x=\"" + num(px + 3) + "\" y=\"" + num(y1 + 12) + "\" font-size=\"10\" fill=\"#666\">" + esc(label) + "</text>\n";
    }
    std::vector<std::string> labels, colours;
    std::vector<int> styles;
    std::vector<PointLabel> point_labels;
    for (std::size_t i = 0; i < p.series.size(); ++i) {
        const auto& se = p.series[i];
        const std::string c = colour(i);
        labels.push_back(se.label);
        colours.push_back(c);
        styles.push_back(se.lines ? (se.dashed ? 3 : 1) : 2);
        std::string path;
        for (const auto& [x, y] : se.points) {
            if (!std::isfinite(x) || !std::isfinite(y) || (p.logx && x <= 0) || (p.logy && y <= 0)) continue;
            path += (path.empty() ? "M" : " L") + num(xa.map(x, x0, x1)) + " " + num(ya.map(y, y0, y1));
        }
        if (se.lines && !path.empty())
            s += "<path d=\"" + path + "\" fill=\"none\" stroke=\"" + c + "\" stroke-width=\"2\"" +
                 (se.dashed ? " stroke-dasharray=\"6,4\"" : "") + "/>\n";
        for (std::size_t k = 0; k < se.points.size(); ++k) {
            const auto [x, y] = se.points[k];
            if (!std::isfinite(x) || !std::isfinite(y) || (p.logx && x <= 0) || (p.logy && y <= 0)) continue;
            const double px = xa.map(x, x0, x1), py = ya.map(y, y0, y1);
            if (se.markers) s += "<circle cx=\"" + num(px) + "\" cy=\"" + num(py) + "\" r=\"3.5\" fill=\"" + c + "\"/>\n";
            if (k < se.point_labels.size() && !se.point_labels[k].empty()) point_labels.push_back({px, py, se.point_labels[k], c});
        }
    }
    if (fixed_y) s += "</g>\n";
    s += place_labels(point_labels, x0, x1, y1, y0);
    s += legend(labels, colours, styles);
    return s + "</svg>\n";
}

std::string svg_bar_plot(const BarPlot& p) {
    double lo = std::numeric_limits<double>::infinity(), hi = 0;
    for (const auto& g : p.values)
        for (const auto& b : g) {
            double sum = 0;
            for (double v : b)
                if (std::isfinite(v)) {
                    sum += v;
                    lo = std::min(lo, v);
                }
            hi = std::max(hi, sum);
        }
    const Axis ya = p.logy ? make_axis(std::isfinite(lo) ? lo : 1, hi, true, false) : make_axis(0, hi, false, true);
    std::string s = frame_and_axes(p.title, "", p.ylabel, ya, nullptr);
    const double x0 = L, x1 = W - R, y0 = H - B, y1 = T;
    const double gw = (x1 - x0) / double(std::max<std::size_t>(1, p.groups.size()));
    const double bw = gw * 0.8 / double(std::max<std::size_t>(1, p.bars.size()));
    for (std::size_t g = 0; g < p.groups.size(); ++g) {
        const double gx = x0 + gw * double(g) + gw * 0.1;
        s += "<text x=\"" + num(x0 + gw * (double(g) + 0.5)) + "\" y=\"" + num(y0 + 16) + "\" text-anchor=\"middle\">" + esc(p.groups[g]) +
             "</text>\n";
        for (std::size_t b = 0; b < p.bars.size(); ++b) {
            if (g >= p.values.size() || b >= p.values[g].size()) continue;
            double base = 0;
            for (std::size_t c = 0; c < p.values[g][b].size(); ++c) {
                const double v = p.values[g][b][c];
                if (!std::isfinite(v) || v <= 0) continue;
                const double top = base + v;
                const double py0 = p.logy && base <= 0 ? y0 : ya.map(base, y0, y1);
                const double py1 = ya.map(top, y0, y1);
                const double opacity = p.components.size() > 1 ? (c == 0 ? 1.0 : 0.45) : 1.0;
                s += "<rect x=\"" + num(gx + bw * double(b)) + "\" y=\"" + num(std::min(py0, py1)) + "\" width=\"" + num(bw * 0.92) +
                     "\" height=\"" + num(std::max(0.5, std::abs(py0 - py1))) + "\" fill=\"" + colour(b) + "\" fill-opacity=\"" +
                     num(opacity) + "\"><title>" + esc(p.groups[g] + " " + p.bars[b] + (p.components.empty() ? "" : " " + p.components[c]) +
                                                    ": " + tick_label(v)) +
                     "</title></rect>\n";
                base = top;
            }
        }
    }
    std::vector<std::string> colours;
    for (std::size_t b = 0; b < p.bars.size(); ++b) colours.push_back(colour(b));
    s += legend(p.bars, colours, std::vector<int>(p.bars.size(), 0));
    if (p.components.size() > 1) {
        const double ly = T + 8 + 18 * double(p.bars.size()) + 10;
        s += "<text x=\"" + num(W - R + 14) + "\" y=\"" + num(ly + 4) + "\" font-size=\"11\">solid: " + esc(p.components[0]) + "</text>\n";
        s += "<text x=\"" + num(W - R + 14) + "\" y=\"" + num(ly + 20) + "\" font-size=\"11\">light: " + esc(p.components[1]) + "</text>\n";
    }
    return s + "</svg>\n";
}

} // namespace dynbvh::study
