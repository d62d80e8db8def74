#include "report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <set>

#include "crossover.hpp"
#include "output.hpp"
#include "svg.hpp"
#include "tables.hpp"
#include "thesis.hpp"

namespace dynbvh::study {

namespace {

bool is_embree_name(const std::string& b) { return b.rfind("embree", 0) == 0; }

std::string pct(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3g%%", x);
    return buf;
}

std::string ratio(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, x >= 10 ? "%.0fx" : "%.2fx", x);
    return buf;
}

/// The line frame_ms(R) = build + R * trace_per_ray of scene x builder, from every resolution.
CostLine cost_line(const StudyResults& r, const std::string& scene, const std::string& builder) {
    CostLine c;
    c.label = builder;
    double build = 0, trace = 0, rays = 0;
    std::size_t n = 0;
    for (const auto& g : r.groups) {
        if (g.scene != scene || g.builder != builder) continue;
        for (const auto& f : g.records) {
            build += f.build_ms;
            trace += f.trace_ms;
            rays += double(g.res.rays());
            ++n;
        }
    }
    c.build_ms = n ? build / double(n) : 0;
    c.trace_ms_per_ray = rays > 0 ? trace / rays : 0;
    return c;
}

/// Frame time of each line relative to the lowest of all lines at the same ray count, against rays per
/// frame (log x, linear y from 1 = fastest): on log-log axes of absolute frame time the lines merge where
/// tracing dominates; as ratios they stay apart and the winner is the line on 1.
LinePlot relative_frame_plot(const std::string& title, const std::vector<CostLine>& lines, const std::vector<bool>& dashed,
                             const std::vector<Resolution>& res) {
    constexpr double cap = 3;   // ratios above are cut at the frame: the interesting part is near 1
    LinePlot p;
    p.title = title;
    p.xlabel = "rays per frame";
    p.ylabel = "frame time / lowest at that ray count";
    p.logx = true;
    for (const auto& x : res) p.xmarks.push_back({double(x.rays()), x.str()});
    std::vector<double> rays;
    for (double e = 3; e <= 8.001; e += 0.05) rays.push_back(std::pow(10.0, e));
    double top = 1;
    for (std::size_t i = 0; i < lines.size(); ++i) {
        Series se;
        se.label = lines[i].label;
        se.markers = false;
        se.dashed = i < dashed.size() && dashed[i];
        for (double n : rays) {
            const double best = lowest_at(lines, n);
            const double y = best > 0 ? lines[i].at(n) / best : 1;
            se.points.push_back({n, y});
            top = std::max(top, std::min(y, cap));
        }
        p.series.push_back(se);
    }
    top = std::max(top, 1.05);
    p.ymin = 1 - 0.03 * (top - 1);
    p.ymax = top + 0.03 * (top - 1);
    return p;
}

std::string resolution_note(const std::vector<Resolution>& res) {
    std::string s = "(";
    for (std::size_t i = 0; i < res.size(); ++i) s += (i ? ", " : "") + res[i].str() + " = " + format_rays(double(res[i].rays()));
    return s + " rays per frame)";
}

/// How much the repetitions of one configuration disagree: per list, the spread (max - min) / mean of
/// the per-repetition mean build and trace times; the sentence gives the median and the largest.
std::string noise_sentence(const std::vector<const std::vector<FrameRecord>*>& lists, const std::string& where) {
    std::vector<double> b, t;
    for (const auto* l : lists) {
        std::map<std::uint32_t, std::pair<double, double>> sum;   // rep -> (build, trace)
        std::map<std::uint32_t, std::size_t> n;
        for (const auto& f : *l) {
            sum[f.rep].first += f.build_ms;
            sum[f.rep].second += f.trace_ms;
            ++n[f.rep];
        }
        if (sum.size() < 2) continue;
        double bmin = 1e300, bmax = 0, tmin = 1e300, tmax = 0, bm = 0, tm = 0;
        for (const auto& [rep, v] : sum) {
            const double bb = v.first / double(n[rep]), tt = v.second / double(n[rep]);
            bmin = std::min(bmin, bb);
            bmax = std::max(bmax, bb);
            tmin = std::min(tmin, tt);
            tmax = std::max(tmax, tt);
            bm += bb / double(sum.size());
            tm += tt / double(sum.size());
        }
        if (bm > 0) b.push_back(100 * (bmax - bmin) / bm);
        if (tm > 0) t.push_back(100 * (tmax - tmin) / tm);
    }
    if (b.empty() || t.empty()) return "";
    std::sort(b.begin(), b.end());
    std::sort(t.begin(), t.end());
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "%s, repetitions of one configuration differed by %.0f%% in trace time and %.0f%% in build time (median; "
                  "up to %.0f%% and %.0f%%): smaller differences are noise on this machine.",
                  where.c_str(), t[t.size() / 2], b[b.size() / 2], t.back(), b.back());
    return buf;
}

} // namespace

std::vector<std::string> study_conclusions(const StudyResults& r) {
    std::vector<std::string> out;
    if (r.groups.empty()) return out;
    // Best FPS per scene and resolution.
    for (const auto& s : r.scenes) {
        std::string line = "On " + s.name + ", the highest FPS";
        bool first = true;
        for (const auto& res : r.options.resolutions) {
            const GroupResult* best = nullptr;
            double best_fps = -1;
            for (const auto& b : r.builders) {
                const GroupResult* g = find_group(r, s.name, b, res);
                if (!g || g->records.empty()) continue;
                const double f = g->summary().fps;
                if (f > best_fps) {
                    best_fps = f;
                    best = g;
                }
            }
            if (!best) continue;
            line += std::string(first ? " at " : "; at ") + res.str() + " is " + best->builder + "'s (" + fmt(best_fps) + ")";
            first = false;
        }
        if (!first) out.push_back(line + ".");
    }
    // Crossovers among all builders, then among ours only.
    for (const auto& s : r.scenes) {
        std::vector<CostLine> all, ours;
        for (const auto& b : r.builders) {
            if (records_all_res(r, s.name, b).empty()) continue;
            const CostLine c = cost_line(r, s.name, b);
            all.push_back(c);
            if (!is_embree_name(b)) ours.push_back(c);
        }
        out.push_back(envelope_sentence(s.name, lower_envelope(all)));
        if (ours.size() != all.size() && !ours.empty())
            out.push_back(envelope_sentence(s.name, lower_envelope(ours), "dynbvh builders only"));
    }
    out.push_back("Frame time is modelled as build + rays x (trace time per ray), both measured; crossovers are where these lines "
                  "meet " + resolution_note(r.options.resolutions) + ".");
    {
        std::vector<const std::vector<FrameRecord>*> lists;
        for (const auto& g : r.groups) lists.push_back(&g.records);
        const std::string noise = noise_sentence(lists, "In this study");
        if (!noise.empty()) out.push_back(noise);
        else out.push_back("One repetition only: run with --reps 3 or more to see how much of each difference is noise.");
    }
    // Against the thesis (full-size scenes only).
    {
        double lo = std::numeric_limits<double>::infinity(), hi = 0;
        std::string lo_at;
        std::size_t n = 0;
        for (const auto& s : r.scenes) {
            if (!s.full_size() || s.frames_used.size() != s.frames_total) continue;
            for (const auto& b : r.builders)
                for (const auto& res : r.options.resolutions) {
                    const auto th = thesis::value(thesis::Metric::fps, b, s.name, res);
                    const GroupResult* g = find_group(r, s.name, b, res);
                    if (!th || !g || g->records.empty()) continue;
                    const double q = g->summary().fps / *th;
                    ++n;
                    hi = std::max(hi, q);
                    if (q < lo) {
                        lo = q;
                        lo_at = b + " on " + s.name + " at " + res.str();
                    }
                }
        }
        if (n == 0) {
            out.push_back("No scene ran at the thesis's size with all its frames, so no FPS is compared with the thesis's (run "
                          "without --quick and --frames; --full is the thesis's protocol).");
        } else {
            out.push_back("Against the thesis's " + std::to_string(n) + " FPS figures (its 12 threads, our " + std::to_string(r.threads) +
                          "): " + ratio(lo) + " (" + lo_at + ") to " + ratio(hi) + " faster; the 10x target is " +
                          (lo >= 10 ? "met everywhere." : "missed at least once."));
        }
    }
    // Against Embree: best frame time and trace speed.
    for (const auto& s : r.scenes) {
        for (const auto& res : r.options.resolutions) {
            const GroupResult *ours = nullptr, *theirs = nullptr, *ours_fast = nullptr, *theirs_fast = nullptr;
            for (const auto& b : r.builders) {
                const GroupResult* g = find_group(r, s.name, b, res);
                if (!g || g->records.empty()) continue;
                const Summary sm = g->summary();
                const GroupResult*& best = is_embree_name(b) ? theirs : ours;
                const GroupResult*& fast = is_embree_name(b) ? theirs_fast : ours_fast;
                if (!best || sm.mean_frame_ms() < best->summary().mean_frame_ms()) best = g;
                if (!fast || sm.mrays_per_s > fast->summary().mrays_per_s) fast = g;
            }
            if (!ours || !theirs) continue;
            const Summary a = ours->summary(), b = theirs->summary();
            const double q = b.mean_frame_ms() / a.mean_frame_ms();
            out.push_back("At " + res.str() + " on " + s.name + ", our best frame time is " + fmt(a.mean_frame_ms()) + " ms (" +
                          ours->builder + "), Embree's best " + fmt(b.mean_frame_ms()) + " ms (" + theirs->builder + "): " +
                          (q >= 1 ? "ours is " + ratio(q) + " faster" : "Embree is " + ratio(1 / q) + " faster") +
                          "; fastest tracing: " + fmt(ours_fast->summary().mrays_per_s) + " Mrays/s (" + ours_fast->builder + ") vs " +
                          fmt(theirs_fast->summary().mrays_per_s) + " Mrays/s (" + theirs_fast->builder + ").");
        }
    }
    // Quality: does the lower SAH trace faster?
    for (const auto& s : r.scenes) {
        const Resolution res = r.options.resolutions.back();
        std::vector<std::pair<double, double>> pts;   // (sah, trace)
        std::string best_sah, best_trace;
        double bs = std::numeric_limits<double>::infinity(), bt = bs;
        for (const auto& b : r.builders) {
            const GroupResult* g = find_group(r, s.name, b, res);
            if (!g || g->records.empty()) continue;
            const Summary sm = g->summary();
            if (!sm.mean_sah) continue;
            if (*sm.mean_sah < bs) {
                bs = *sm.mean_sah;
                best_sah = b;
            }
            if (sm.mean_trace_ms < bt) {
                bt = sm.mean_trace_ms;
                best_trace = b;
            }
        }
        if (!best_sah.empty())
            out.push_back("On " + s.name + " the lowest SAH is " + best_sah + "'s (" + fmt(bs) + ") and the fastest trace at " + res.str() +
                          " among our builders is " + best_trace + "'s (" + fmt(bt) + " ms)" +
                          (best_sah == best_trace ? ": SAH predicted the winner." : ": SAH did not predict the winner."));
    }
    return out;
}

std::vector<std::string> effects_conclusions(const StudyResults& r) {
    std::vector<std::string> out;
    for (const auto& s : r.scenes) {
        for (const auto& res : r.options.resolutions) {
            struct Row {
                std::string builder;
                EffectsRecord e;
                double n;
                std::optional<double> sah;
            };
            std::vector<Row> rows;
            for (const auto& b : r.builders) {
                const GroupResult* g = find_group(r, s.name, b, res);
                if (!g || g->records.empty()) continue;
                if (const auto e = sum_effects(g->records)) rows.push_back({b, *e, double(g->records.size()), g->summary().mean_sah});
            }
            if (rows.empty()) continue;
            const EffectsRecord& e0 = rows.front().e;
            std::string sent = s.name + " at " + res.str() + " with effects: per frame " + format_rays(double(e0.rays[0]) / rows.front().n) +
                               " primary, " + format_rays(double(e0.rays[1]) / rows.front().n) + " shadow, " +
                               format_rays(double(e0.rays[2]) / rows.front().n) + " reflection and " +
                               format_rays(double(e0.rays[3]) / rows.front().n) + " refraction rays";
            if (e0.rays[1] + e0.rays[2] + e0.rays[3] == 0) {
                out.push_back(sent + ": the scene calls for no secondary rays.");
                continue;
            }
            sent += ". Tracing time per ray relative to the fastest builder:";
            // Time per ray, not per frame: builders may differ by a few rays where closest hits tie.
            for (std::size_t k = 0; k < 4; ++k) {
                if (e0.rays[k] == 0) continue;
                double best = std::numeric_limits<double>::infinity();
                std::string best_name;
                for (const auto& row : rows) {
                    const double per = row.e.rays[k] ? row.e.ms[k] / double(row.e.rays[k]) : std::nan("");
                    if (per < best) {
                        best = per;
                        best_name = row.builder;
                    }
                }
                sent += std::string(k == 0 ? " " : "; ") + effect_kind_names[k] + " ";
                bool first = true;
                for (const auto& row : rows) {
                    const double per = row.e.rays[k] ? row.e.ms[k] / double(row.e.rays[k]) : std::nan("");
                    sent += (first ? "" : ", ") + row.builder + " " + ratio(per / best);
                    first = false;
                }
            }
            sent += ".";
            out.push_back(sent);
            // Does the better tree (lowest SAH) pay off more for secondary rays than for primary rays?
            const Row* lo = nullptr;
            const Row* hi = nullptr;
            for (const auto& row : rows) {
                if (!row.sah) continue;
                if (!lo || *row.sah < *lo->sah) lo = &row;
                if (!hi || *row.sah > *hi->sah) hi = &row;
            }
            const auto per_ray = [](const EffectsRecord& e, bool secondary) {
                const double rays = secondary ? double(e.rays[1] + e.rays[2] + e.rays[3]) : double(e.rays[0]);
                const double ms = secondary ? e.ms[1] + e.ms[2] + e.ms[3] : e.ms[0];
                return rays > 0 ? ms / rays : std::nan("");
            };
            if (lo && hi && lo != hi) {
                const double gp = per_ray(hi->e, false) / per_ray(lo->e, false), gs = per_ray(hi->e, true) / per_ray(lo->e, true);
                out.push_back(s.name + " at " + res.str() + ": " + lo->builder + " (SAH " + fmt(*lo->sah) + ") traces primary rays " +
                              ratio(gp) + " and secondary rays " + ratio(gs) + " as fast as " + hi->builder + " (SAH " + fmt(*hi->sah) +
                              "): the better tree pays off " + (gs > gp ? "more" : "less") + " for the secondary rays.");
            }
        }
    }
    return out;
}

std::vector<std::string> sweep_conclusions(const StudyResults& r) {
    std::vector<std::string> out;
    for (const auto& s : r.sweep_scenes) {
        std::vector<std::string> groups;
        for (const auto& x : r.sweep)
            if (x.scene == s.name && std::find(groups.begin(), groups.end(), x.group) == groups.end()) groups.push_back(x.group);
        {
            std::vector<const std::vector<FrameRecord>*> lists;
            std::set<std::string> seen;
            for (const auto& x : r.sweep)
                if (x.scene == s.name && seen.insert(x.setting).second) lists.push_back(&x.records);
            const std::string noise = noise_sentence(lists, "On " + s.name);
            if (!noise.empty()) out.push_back(noise);
        }
        for (const auto& grp : groups) {
            std::vector<const SweepResult*> xs;
            for (const auto& x : r.sweep)
                if (x.scene == s.name && x.group == grp) xs.push_back(&x);
            if (xs.empty()) continue;
            const Resolution res = xs.front()->res;
            const SweepResult* best = nullptr;
            const SweepResult* best_sah = nullptr;
            std::vector<CostLine> lines;
            for (const auto* x : xs) {
                const Summary sm = x->summary();
                if (!best || sm.mean_frame_ms() < best->summary().mean_frame_ms()) best = x;
                if (sm.mean_sah && (!best_sah || *sm.mean_sah < *best_sah->summary().mean_sah)) best_sah = x;
                lines.push_back({x->value, sm.mean_build_ms, sm.mean_trace_ms / double(res.rays())});
            }
            const Summary f = xs.front()->summary(), l = xs.back()->summary();
            std::string line;
            if (xs.front()->ordered) {
                line = grp + " on " + s.name + ": from " + xs.front()->value + " to " + xs.back()->value + ", build " +
                       fmt(f.mean_build_ms) + " -> " + fmt(l.mean_build_ms) + " ms, trace " + fmt(f.mean_trace_ms) + " -> " +
                       fmt(l.mean_trace_ms) + " ms";
                if (f.mean_sah && l.mean_sah) line += ", SAH " + fmt(*f.mean_sah) + " -> " + fmt(*l.mean_sah);
            } else {
                // Alternatives: each against the first.
                line = grp + " on " + s.name + ", against " + xs.front()->value + ":";
                for (std::size_t i = 1; i < xs.size(); ++i) {
                    const Summary m = xs[i]->summary();
                    auto rel = [](double a, double b) {
                        char buf[32];
                        std::snprintf(buf, sizeof buf, "%+.0f%%", b > 0 ? 100.0 * (a - b) / b : 0.0);
                        return std::string(buf);
                    };
                    line += std::string(i > 1 ? ";" : "") + " " + xs[i]->value + " build " + rel(m.mean_build_ms, f.mean_build_ms) +
                            ", trace " + rel(m.mean_trace_ms, f.mean_trace_ms);
                    if (m.mean_sah && f.mean_sah) line += ", SAH " + rel(*m.mean_sah, *f.mean_sah);
                }
            }
            line += "; lowest frame time at " + res.str() + ": " + best->value + " (" + fmt(best->summary().mean_frame_ms()) + " ms)";
            if (best_sah) line += "; lowest SAH: " + best_sah->value;
            out.push_back(line + ".");
            if (lines.size() > 1) out.push_back(envelope_sentence(s.name, lower_envelope(lines), grp));
            // Hit differences against the reference.
            for (const auto* x : xs) {
                if (x->compared_pixels == 0 || (x->changed == 0 && x->lost == 0 && x->gained == 0)) continue;
                const double n = double(x->compared_pixels);
                out.push_back(grp + " " + x->value + " on " + s.name + ": " + pct(100.0 * double(x->changed) / n) +
                              " of hits on another triangle, " + pct(100.0 * double(x->lost) / n) + " lost, " +
                              pct(100.0 * double(x->gained) / n) + " gained, against " + r.sweep_reference + ".");
            }
            bool all_same = true;
            for (const auto* x : xs)
                if (x->changed || x->lost || x->gained) all_same = false;
            if (all_same && xs.size() > 1)
                out.push_back(grp + " on " + s.name + ": every setting hit exactly the same triangle as the reference on every pixel.");
        }
    }
    return out;
}

namespace {

bool has_strategy(const GroupResult& g) { return !g.records.empty() && g.records.front().strategy.has_value(); }

/// For a strategy's name ("auto", "auto:lbvh:wide=4"), the per-frame rebuild with its builder ("ploc",
/// "lbvh:wide=4") and always-refit ("refit", "refit:wide=4") as the study names them.
std::pair<std::string, std::string> strategy_baselines(const std::string& name) {
    const BuilderSpec a = parse_builder(name);
    BuilderSpec rebuild = a, refit = a;
    rebuild.kind = a.over;
    refit.kind = Kind::refit;
    for (BuilderSpec* b : {&rebuild, &refit}) {
        b->over = BuilderSpec{}.over;
        b->threshold = BuilderSpec{}.threshold;
        b->async = false;
        b->amortized = BuilderSpec{}.amortized;
    }
    refit.over = a.over;   // always-refit over the strategy's own builder ("auto:lbvh" -> "refit:lbvh")
    if (rebuild.kind != Kind::ploc) rebuild.radius = BuilderSpec{}.radius;
    if (refit.over != Kind::ploc) refit.radius = BuilderSpec{}.radius;
    return {rebuild.name(), refit.name()};
}

/// One table: per scene x strategy x resolution, the decisions counted and the frame time beside
/// always-rebuild (same builder) and always-refit, when those ran too.
Table strategy_table(const StudyResults& r) {
    Table t;
    t.title = "Strategies: refit or rebuild per frame";
    t.header = {"scene", "strategy", "resolution", "frames", "refit", "rebuild", "swap", "frame ms", "rebuild every frame",
                "always refit", "vs better of both"};
    for (const auto& g : r.groups) {
        if (!has_strategy(g)) continue;
        std::size_t n[3] = {0, 0, 0};
        for (const auto& f : g.records) {
            if (!f.strategy) continue;
            n[0] += f.strategy->decision == "refit";
            n[1] += f.strategy->decision == "rebuild";
            n[2] += f.strategy->decision == "swap";
        }
        const double ms = g.summary().mean_frame_ms();
        const auto [rebuild_name, refit_name] = strategy_baselines(g.builder);
        const GroupResult* rb = find_group(r, g.scene, rebuild_name, g.res);
        const GroupResult* rf = find_group(r, g.scene, refit_name, g.res);
        const double rb_ms = rb && !rb->records.empty() ? rb->summary().mean_frame_ms() : std::nan("");
        const double rf_ms = rf && !rf->records.empty() ? rf->summary().mean_frame_ms() : std::nan("");
        const double best = std::isfinite(rb_ms) && std::isfinite(rf_ms) ? std::min(rb_ms, rf_ms)
                            : std::isfinite(rb_ms)                        ? rb_ms
                                                                          : rf_ms;
        t.rows.push_back({g.scene, g.builder, g.res.str(), std::to_string(g.records.size()), std::to_string(n[0]),
                          std::to_string(n[1]), std::to_string(n[2]), fmt(ms),
                          std::isfinite(rb_ms) ? fmt(rb_ms) + " (" + rebuild_name + ")" : "-",
                          std::isfinite(rf_ms) ? fmt(rf_ms) + " (" + refit_name + ")" : "-",
                          std::isfinite(best) && best > 0 ? ratio(ms / best) : "-"});
    }
    t.notes.push_back("frame ms = mean build (refit, rebuild or swap; over block trees, the default, the policy holds the traced "
                      "block tree itself, refitted in place, and its SAHs in the tables are that wide tree's, sah_cost of a WideBvh; "
                      "with blocks=0 plus the wide-tree conversion of its binary tree) + trace per frame. "
                      "A strategy refits its tree every frame and rebuilds (dynbvh::Dynamic, include/dynbvh/dynamic.hpp) "
                      "once the trace time it estimates refitting has lost since its last rebuild (each frame's measured "
                      "trace time x (1 - rebuilt SAH / refitted SAH)) reaches that rebuild's time (rule=amortized, the "
                      "default), or when the refitted SAH exceeds its threshold times the SAH right after its last rebuild "
                      "(rule=sah); the first frame always rebuilds. Once two frames in a row rebuilt at their first "
                      "refit by a clear margin (a loss of twice the rebuild's time; rule=sah: twice the threshold), "
                      "frames rebuild without refitting (reason streak), every 8th frame of such a run (DynamicConfig's "
                      "probe_every) refitting to check. \"always refit\" is the study's refit over the strategy's builder (refit: PLOC at the first frame, "
                      "refitted after; auto:lbvh against refit:lbvh); \"vs better of both\" = frame ms / the lower of the two (the issue-13 target is <= 1.05x).");
    return t;
}

bool is_two_level_name(const std::string& b) { return b.rfind("two-level", 0) == 0 || b == "embree-two-level"; }

/// Per scene x two-level variant x resolution: frame time beside the best per-frame rebuild (any builder
/// that does not keep a tree across frames, ours or Embree's).
Table two_level_table(const StudyResults& r) {
    Table t;
    t.title = "Two-level: objects with their own trees, a top-level tree per frame";
    t.header = {"scene", "strategy", "resolution", "frames", "build ms", "trace ms", "frame ms", "best per-frame rebuild",
                "vs best rebuild", "vs embree-two-level"};
    for (const auto& g : r.groups) {
        if (!is_two_level_name(g.builder) || g.records.empty()) continue;
        const Summary s = g.summary();
        double best = std::nan("");
        std::string best_name;
        for (const auto& h : r.groups) {
            if (h.scene != g.scene || !(h.res == g.res) || h.records.empty()) continue;
            const BuilderSpec b = parse_builder(h.builder);
            if (b.stateful()) continue;
            const double ms = h.summary().mean_frame_ms();
            if (!(ms >= best)) {
                best = ms;
                best_name = h.builder;
            }
        }
        const GroupResult* e = find_group(r, g.scene, "embree-two-level", g.res);
        const double e_ms = e && !e->records.empty() && g.builder != "embree-two-level" ? e->summary().mean_frame_ms() : std::nan("");
        t.rows.push_back({g.scene, g.builder, g.res.str(), std::to_string(g.records.size()), fmt(s.mean_build_ms),
                          fmt(s.mean_trace_ms), fmt(s.mean_frame_ms()),
                          std::isfinite(best) ? fmt(best) + " (" + best_name + ")" : "-",
                          std::isfinite(best) && best > 0 ? ratio(s.mean_frame_ms() / best) : "-",
                          std::isfinite(e_ms) && e_ms > 0 ? ratio(s.mean_frame_ms() / e_ms) : "-"});
    }
    t.notes.push_back("build ms = setting each instance's transform, refitting or rebuilding the deforming objects and "
                      "rebuilding the top level; trace = dynbvh::TwoLevel::intersect (binary trees, robust tests). The "
                      "built-in scenes give world-space triangles only: each rigid object's triangles are taken into object "
                      "space once, from the first frame (or the first frame after its layout changed, a fracture), "
                      "through the inverse of that frame's transform (timed as part of that frame's build), "
                      "so its later frames are that mesh under the frame's transform: equal to the scene's triangles up to "
                      "rounding. Animated objects with an identity transform (cloth) are deforming: given every frame. "
                      "The issue-13 targets on n-body: <= 0.5x the best per-frame rebuild and <= 1x embree-two-level.");
    return t;
}

/// The frame time of every frame, one line per builder: where a strategy rebuilt (R) or swapped (S).
LinePlot per_frame_plot(const StudyResults& r, const std::string& scene, Resolution res) {
    LinePlot p;
    p.title = scene + " at " + res.str() + ": frame time per frame";
    p.xlabel = "frame";
    p.ylabel = "build + trace, ms";
    p.logy = true;
    for (const auto& b : r.builders) {
        const GroupResult* g = find_group(r, scene, b, res);
        if (!g || g->records.empty()) continue;
        // mean over the repetitions of each frame
        std::map<std::uint32_t, std::pair<double, std::size_t>> per;
        std::map<std::uint32_t, std::string> mark;
        for (const auto& f : g->records) {
            auto& [sum, n] = per[f.frame];
            sum += f.build_ms + f.trace_ms;
            ++n;
            if (f.rep == 0 && f.strategy)
                mark[f.frame] = f.strategy->decision == "rebuild" ? "R" : f.strategy->decision == "swap" ? "S" : "";
        }
        Series se;
        se.label = b;
        se.dashed = is_embree_name(b);
        for (const auto& [frame, sn] : per) {
            se.points.push_back({double(frame), sn.first / double(sn.second)});
            if (has_strategy(*g)) se.point_labels.push_back(mark[frame]);
        }
        p.series.push_back(std::move(se));
    }
    return p;
}

} // namespace

std::string write_report(const StudyResults& r) {
    namespace fs = std::filesystem;
    const fs::path dir = r.options.out;
    std::vector<std::pair<std::string, std::string>> figures;   // (file, caption)
    auto save = [&](const std::string& file, const std::string& svg, const std::string& caption) {
        write_text((dir / file).string(), svg);
        figures.push_back({file, caption});
    };
    std::string md = "# dynbvh study\n\n";
    md += "`" + r.options.command_line + "`\n\n";
    md += "| | |\n| --- | --- |\n";
    md += "| date | " + r.machine.date + " |\n";
    md += "| machine | " + r.machine.cpu + ", " + std::to_string(r.machine.cores) + " cores, " + fmt(r.machine.memory_gib) + " GiB |\n";
    md += "| compiler | " + r.machine.compiler + " |\n";
    md += "| backend | " + r.backend + ", " + std::to_string(r.threads) + " threads |\n";
    md += "| Embree | " + (r.machine.embree.empty() ? std::string("not built in") : r.machine.embree) + " |\n";
    md += "| wall time | " + fmt(r.wall_s) + " s |\n\n";
    md += "Protocol (thesis chapter 4-5): for every scene x builder x resolution x repetition, every selected frame is produced "
          "first (untimed), then built (timed) and traced with one primary ray per pixel from the scene's camera (timed; "
          "16x16 pixel tiles in parallel, closest hit with the robust box test and watertight triangles for our builders, "
          "whose wide trees hold their leaves' triangles in SIMD blocks (`blocks=0`: index leaves); " +
          std::string(r.options.packets ? "rays in packets: `dynbvh::intersect(tree, tris, RayPacket<float, 32>)` on 8x4 pixels (two 4x4 halves) for "
                                          "wide trees and two-level scenes, single rays on binary trees; `rtcIntersect16` "
                                          "on 4x4 pixels for Embree (`--rays single`: one ray at a time)"
                                        : "one ray at a time: `dynbvh::intersect`, `rtcIntersect1` for Embree (`--rays packet`: packets)") +
          "). FPS = frames / (total build + total trace). SAH with Ct = 3, "
          "Ci = 2 (not available for Embree). Raw data: [study.json](study.json), [study.csv](study.csv).\n\n";
    if (r.options.frame_step == 0 && r.options.frames > 0)
        md += "Frames: " + std::to_string(r.options.frames) + " spread evenly over each animation, so refit (and embree-refit) "
              "follow several frames of motion per step: harder for them than consecutive frames.\n\n";

    if (!r.scenes.empty()) {
        md += "## Scenes\n\n" + render_markdown(scenes_table(r.scenes));
        md += "## Results\n\n";
        for (const auto& t : study_tables(r)) md += render_markdown(t);
        md += "## Conclusions (computed from the data above)\n\n";
        for (const auto& c : study_conclusions(r)) md += "- " + c + "\n";
        md += "\n";
        if (std::any_of(r.groups.begin(), r.groups.end(), has_strategy)) {
            md += "## Strategies\n\n";
            md += render_markdown(strategy_table(r));
            md += "Every frame's decision (refit, rebuild, swap) with its SAHs is in study.json (`per_frame`: `decision`, "
                  "`reason`, `sah_before`, `sah_after`, `sah_rebuilt`) and study.csv; the plots of frame time per frame "
                  "(fig_frames_*.svg, under Figures) mark a strategy's rebuilds R and swaps S.\n\n";
        }
        if (std::any_of(r.groups.begin(), r.groups.end(), [](const GroupResult& g) { return is_two_level_name(g.builder); })) {
            md += "## Two-level\n\n" + render_markdown(two_level_table(r));
            std::string skipped;
            for (const auto& sk : r.skipped)
                if (is_two_level_name(sk.builder)) skipped += " " + sk.builder + " on " + sk.scene + " (" + sk.reason + ");";
            if (!skipped.empty()) md += "Not run on:" + skipped + " see Skipped.\n\n";
        }

        // Figure 5.5-like: build time against triangles.
        {
            LinePlot p;
            p.title = "Build time vs triangles";
            p.xlabel = "triangles";
            p.ylabel = "mean build time per frame, ms";
            p.logx = p.logy = true;
            for (const auto& b : r.builders) {
                Series se;
                se.label = b;
                for (const auto& s : r.scenes) {
                    const auto recs = records_all_res(r, s.name, b);
                    if (recs.empty()) continue;
                    double tris = 0;
                    for (const auto& f : recs) tris += double(f.triangles);
                    se.points.push_back({tris / double(recs.size()), summarize(recs, 0).mean_build_ms});
                }
                std::sort(se.points.begin(), se.points.end());
                if (!se.points.empty()) p.series.push_back(se);
            }
            save("fig_build_vs_triangles.svg", svg_line_plot(p), "Mean build time per frame against the scene's triangle count (cf. thesis fig. 5.5).");
        }
        // Trace time per scene, one chart per resolution.
        for (const auto& res : r.options.resolutions) {
            BarPlot p;
            p.title = "Trace time per frame at " + res.str();
            p.ylabel = "mean trace time per frame, ms";
            p.logy = true;
            p.bars = r.builders;
            for (const auto& s : r.scenes) {
                p.groups.push_back(s.name);
                std::vector<std::vector<double>> row;
                for (const auto& b : r.builders) {
                    const GroupResult* g = find_group(r, s.name, b, res);
                    row.push_back({g && !g->records.empty() ? g->summary().mean_trace_ms : std::nan("")});
                }
                p.values.push_back(row);
            }
            save("fig_trace_" + res.str() + ".svg", svg_bar_plot(p), "Mean trace time per frame at " + res.str() + " (log scale).");
        }
        // Build + trace stacked per builder, per scene and resolution (figs 5.6-5.12).
        for (const auto& s : r.scenes) {
            BarPlot p;
            p.title = s.name + ": frame time = build + trace";
            p.ylabel = "mean time per frame, ms";
            p.bars = r.builders;
            p.components = {"build", "trace"};
            for (const auto& res : r.options.resolutions) {
                p.groups.push_back(res.str());
                std::vector<std::vector<double>> row;
                for (const auto& b : r.builders) {
                    const GroupResult* g = find_group(r, s.name, b, res);
                    if (!g || g->records.empty()) row.push_back({std::nan(""), std::nan("")});
                    else row.push_back({g->summary().mean_build_ms, g->summary().mean_trace_ms});
                }
                p.values.push_back(row);
            }
            save("fig_frame_" + safe_file_name(s.name) + ".svg", svg_bar_plot(p),
                 s.name + ": mean build (solid) and trace (light) time per frame, per builder and resolution (cf. figs 5.6-5.12).");
            // One chart per resolution too: at the lower resolutions the bars are easier to read alone.
            for (std::size_t ri = 0; ri + 1 < r.options.resolutions.size(); ++ri) {
                BarPlot q = p;
                q.title = s.name + " at " + r.options.resolutions[ri].str() + ": build + trace";
                q.groups = {p.groups[ri]};
                q.values = {p.values[ri]};
                save("fig_frame_" + safe_file_name(s.name) + "_" + r.options.resolutions[ri].str() + ".svg", svg_bar_plot(q),
                     s.name + " at " + r.options.resolutions[ri].str() + ": build + trace per builder.");
            }
        }
        // Frame time per frame, every builder and strategy (one chart per scene and resolution).
        for (const auto& s : r.scenes)
            for (const auto& res : r.options.resolutions) {
                const LinePlot p = per_frame_plot(r, s.name, res);
                if (p.series.empty()) continue;
                save("fig_frames_" + safe_file_name(s.name) + "_" + res.str() + ".svg", svg_line_plot(p),
                     s.name + " at " + res.str() + ": build + trace time of every frame, per builder and strategy (log "
                     "scale; R = a strategy rebuilt, S = it swapped in a background rebuild; mean over repetitions).");
            }
        // Frame time against rays per frame (crossovers), relative to the fastest at each ray count.
        for (const auto& s : r.scenes) {
            std::vector<CostLine> lines;
            std::vector<bool> dashed;
            for (const auto& b : r.builders) {
                if (records_all_res(r, s.name, b).empty()) continue;
                lines.push_back(cost_line(r, s.name, b));
                dashed.push_back(is_embree_name(b));
            }
            save("fig_crossover_" + safe_file_name(s.name) + ".svg",
                 svg_line_plot(relative_frame_plot(s.name + ": frame time relative to the fastest builder", lines, dashed,
                                                   r.options.resolutions)),
                 s.name + ": modelled frame time (build + rays x trace cost per ray) divided by the lowest of all builders at "
                          "the same ray count; the builder on 1 wins there (Embree dashed; above 3x cut off).");
        }
        if (const auto fx = effects_tables(r); !fx.empty()) {
            md += "## Effects (--effects auto)\n\n";
            md += "After its primary trace every frame is rendered Whitted-style (bench/render/whitted.hpp, depth " +
                  std::to_string(r.options.effects_depth) +
                  ") through the same structure: shadow rays towards the scene's lights, reflection rays from specular or "
                  "transparent materials, refraction rays (Snell, exact Fresnel, total internal reflection) from transparent "
                  "ones; each kind traced in its own timed passes. The renders below show these effects.\n\n";
            for (const auto& t : fx) md += render_markdown(t);
            for (const auto& c : effects_conclusions(r)) md += "- " + c + "\n";
            md += "\n";
        }
        md += "## Figures\n\n";
        for (const auto& [file, caption] : figures) md += "![" + caption + "](" + file + ")\n\n*" + caption + "*\n\n";
        figures.clear();

        if (!r.images.empty()) {
            if (r.options.effects)
                md += "## Renders\n\nA few frames per scene rendered with the effects the scene calls for (Whitted: shadows, "
                      "reflection, refraction; depth " + std::to_string(r.options.effects_depth) + ").\n\n";
            else
                md += "## Renders\n\nPrimary-ray hits of a few frames per scene (material colour, n.l shading, no shadows; misses are "
                      "background).\n\n";
            std::string last;
            for (const auto& im : r.images) {
                if (im.scene != last) md += "\n**" + im.scene + "**\n\n";
                last = im.scene;
                md += "![" + im.scene + " frame " + std::to_string(im.frame) + "](" + im.file + ") ";
            }
            md += "\n\n";
        }
    }

    if (!r.sweep.empty()) {
        md += "## What accuracy costs in time\n\n";
        md += "Each knob changed alone from the defaults; every frame traced at " + r.sweep.front().res.str() +
              " and compared pixel by pixel with " + r.sweep_reference + ".\n\n";
        for (const auto& t : sweep_tables(r)) md += render_markdown(t);
        md += "### Conclusions (computed)\n\n";
        for (const auto& c : sweep_conclusions(r)) md += "- " + c + "\n";
        md += "\n";
        for (const auto& s : r.sweep_scenes) {
            std::vector<std::string> groups;
            for (const auto& x : r.sweep)
                if (x.scene == s.name && std::find(groups.begin(), groups.end(), x.group) == groups.end()) groups.push_back(x.group);
            for (const auto& grp : groups) {
                std::vector<CostLine> lines;
                for (const auto& x : r.sweep) {
                    if (x.scene != s.name || x.group != grp) continue;
                    const Summary sm = x.summary();
                    lines.push_back({x.value, sm.mean_build_ms, sm.mean_trace_ms / double(x.res.rays())});
                }
                save("fig_sweep_" + safe_file_name(s.name) + "_" + safe_file_name(grp) + ".svg",
                     svg_line_plot(relative_frame_plot(s.name + ": " + grp + ", frame time relative to the fastest", lines, {},
                                                       r.options.resolutions)),
                     s.name + ", " + grp + ": modelled frame time divided by the lowest of all settings at the same ray count "
                                           "(1 = fastest; above 3x cut off).");
            }
            // SAH against trace time for every setting of ours.
            LinePlot q;
            q.title = s.name + ": trace time vs SAH (every setting)";
            q.xlabel = "mean SAH";
            q.ylabel = "mean trace time per frame, ms";
            std::map<std::string, Series> by_group;
            for (const auto& x : r.sweep) {
                if (x.scene != s.name) continue;
                const Summary sm = x.summary();
                if (!sm.mean_sah) continue;
                Series& se = by_group[x.group];
                se.label = x.group;
                se.lines = false;
                se.points.push_back({*sm.mean_sah, sm.mean_trace_ms});
                se.point_labels.push_back(x.value);
            }
            for (auto& [k, se] : by_group) q.series.push_back(se);
            save("fig_sweep_" + safe_file_name(s.name) + "_sah_vs_trace.svg", svg_line_plot(q),
                 s.name + ": does a lower SAH trace faster? One point per setting, labelled with its value.");
        }
        for (const auto& [file, caption] : figures) md += "![" + caption + "](" + file + ")\n\n*" + caption + "*\n\n";
    }

    if (!r.skipped.empty() || !r.notices.empty()) {
        md += "## Skipped\n\n";
        for (const auto& n : r.notices) md += "- " + n + "\n";
        for (const auto& s : r.skipped) md += "- " + s.builder + " on " + s.scene + ": " + s.reason + "\n";
        md += "\n";
    }
    const std::string path = (dir / "report.md").string();
    write_text(path, md);
    return path;
}

} // namespace dynbvh::study
