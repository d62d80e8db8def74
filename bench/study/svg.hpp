// SVG charts written by hand (no plotting dependency): line/scatter plots with linear or log axes,
// and grouped bar charts whose bars may be stacked from several components.
#pragma once

#include <cmath>
#include <string>
#include <utility>
#include <vector>

namespace dynbvh::study {

struct Series {
    std::string label;
    std::vector<std::pair<double, double>> points;
    bool lines = true;
    bool markers = true;
    bool dashed = false;
    std::vector<std::string> point_labels;   ///< text beside each point, in the order of `points`; empty: none
};

struct LinePlot {
    std::string title, xlabel, ylabel;
    bool logx = false, logy = false;
    std::vector<Series> series;
    std::vector<std::pair<double, std::string>> xmarks;   ///< vertical reference lines (e.g. resolutions)
    double ymin = std::nan(""), ymax = std::nan("");      ///< fixed linear y range (NaN: from the data); lines are clipped to it
};

struct BarPlot {
    std::string title, ylabel;
    bool logy = false;
    std::vector<std::string> groups;       ///< x categories
    std::vector<std::string> bars;         ///< one bar per entry in each group (colour)
    std::vector<std::string> components;   ///< stacked parts of each bar, bottom first (shade)
    /// values[group][bar][component]; NaN = no bar.
    std::vector<std::vector<std::vector<double>>> values;
};

std::string svg_line_plot(const LinePlot& p);
std::string svg_bar_plot(const BarPlot& p);

} // namespace dynbvh::study
