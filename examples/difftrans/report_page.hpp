// The page of `difftrans report`: sections of tables, plots (inline SVG) and
// pictures, written as one static HTML file (no scripts, no network; narrow
// screens scroll the tables), a CSV file per table and results.json with
// every number. Each number links to the run that produced it, listed with
// its command at the end of the page.
#pragma once

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "difftrans/io/json.hpp"
#include "report_jobs.hpp"

namespace difftrans::cli::report {

// A table cell: text, the number behind it (for CSV and JSON), and the run it
// comes from ("" for a label or a figure quoted from the paper).
struct Cell {
  std::string text;
  std::optional<double> value;
  std::string job;
};

inline Cell label(std::string text) { return {std::move(text), std::nullopt, ""}; }
inline std::string number_text(double v, int digits) {
  if (!std::isfinite(v)) return "–";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}
inline std::string sci_text(double v, int digits) {
  if (!std::isfinite(v)) return "–";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*e", digits, v);
  return buf;
}
inline Cell number(double v, int digits, std::string job) { return {number_text(v, digits), v, std::move(job)}; }
inline Cell sci(double v, int digits, std::string job) { return {sci_text(v, digits), v, std::move(job)}; }
inline Cell missing(std::string job) { return {"–", std::nullopt, std::move(job)}; }

struct Table {
  std::string id, title, note;
  std::vector<std::string> columns;
  std::vector<std::vector<Cell>> rows;
};

// A scatter plot: points per series, optionally joined; points link to runs.
struct Point {
  double x = 0, y = 0;
  std::string label, job;
  bool marked = false;  // drawn with a ring (the defaults, a Pareto front's members)
};
struct Series {
  std::string name, colour;
  std::vector<Point> points;
  bool joined = false;
  bool dots = true;  // false: the line alone (a front drawn under the points it joins)
};
struct Plot {
  std::string id, title, x_label, y_label, note;
  bool log_x = true, log_y = true;
  std::vector<Series> series;
};

struct Picture {
  std::string file;  // relative to the page
  std::string caption;
};

struct Section {
  std::string id, title, intro;
  std::vector<Table> tables;
  std::vector<Plot> plots;
  std::vector<Picture> pictures;
};

inline std::string html_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}
inline std::string anchor(const std::string& job) {
  std::string a = "run-";
  for (char c : job) a += std::isalnum(static_cast<unsigned char>(c)) ? c : '-';
  return a;
}
inline std::string csv_field(const std::string& s) {
  if (s == "–") return "";  // a number not measured
  if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

// Whether a cell's text is one number (then its CSV field is the full-precision value).
inline bool plain_number(const std::string& text) {
  if (text.empty()) return false;
  char* end = nullptr;
  std::strtod(text.c_str(), &end);
  return end == text.c_str() + text.size();
}

// The SVG of a plot, sized by its viewBox so that it shrinks with the page.
inline std::string plot_svg(const Plot& p) {
  const double W = 640, H = 400, L = 70, R = 16, T = 16, B = 50;
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  const auto tx = [&](double v) { return p.log_x ? std::log10(v) : v; };
  const auto ty = [&](double v) { return p.log_y ? std::log10(v) : v; };
  const auto usable = [&](const Point& q) {
    return std::isfinite(q.x) && std::isfinite(q.y) && (!p.log_x || q.x > 0) && (!p.log_y || q.y > 0);
  };
  for (const auto& s : p.series)
    for (const auto& q : s.points)
      if (usable(q)) {
        x0 = std::min(x0, tx(q.x)), x1 = std::max(x1, tx(q.x));
        y0 = std::min(y0, ty(q.y)), y1 = std::max(y1, ty(q.y));
      }
  if (!(x1 >= x0)) x0 = 0, x1 = 1;
  if (!(y1 >= y0)) y0 = 0, y1 = 1;
  // linear axes: a round step (1, 2 or 5 times a power of ten), about 5 per axis
  const auto nice_step = [](double a, double b) {
    const double raw = (b - a) / 5.0, p10 = std::pow(10.0, std::floor(std::log10(raw)));
    return raw / p10 < 1.5 ? p10 : raw / p10 < 3.5 ? 2 * p10 : raw / p10 < 7.5 ? 5 * p10 : 10 * p10;
  };
  const auto widen = [&](double& a, double& b, bool log) {
    if (log) {
      a = std::floor(a - 1e-9), b = std::ceil(b + 1e-9);
      if (b - a < 1) b = a + 1;
    } else {
      const double pad = b > a ? 0.06 * (b - a) : std::max(0.5, 0.1 * std::abs(a));
      a -= pad, b += pad;
      const double step = nice_step(a, b);
      a = std::floor(a / step) * step, b = std::ceil(b / step) * step;
    }
  };
  widen(x0, x1, p.log_x);
  widen(y0, y1, p.log_y);
  const auto X = [&](double v) { return L + (W - L - R) * (tx(v) - x0) / (x1 - x0); };
  const auto Y = [&](double v) { return T + (H - T - B) * (1 - (ty(v) - y0) / (y1 - y0)); };
  std::string s = "<svg viewBox=\"0 0 640 400\" role=\"img\" aria-label=\"" + html_escape(p.title) +
                  "\" xmlns=\"http://www.w3.org/2000/svg\" font-size=\"12\" font-family=\"sans-serif\">\n"
                  "<rect width=\"640\" height=\"400\" fill=\"white\"/>\n";
  // ticks in axis units (log10 of the value on a log axis); a log axis of at
  // most two decades also gets 2 and 5 times each power of ten
  const auto tick_text = [&](double v, bool log, double a, double b) {
    if (log) {
      const double value = std::pow(10.0, v);
      return std::abs(v - std::round(v)) < 1e-9 ? "1e" + std::to_string(int(std::lround(v))) : number_text(value, std::max(0, int(-std::floor(v))));
    }
    const double step = nice_step(a, b);
    const int digits = std::max(0, int(-std::floor(std::log10(step) + 1e-9)));
    return number_text(std::abs(v) < 1e-12 * step ? 0.0 : v, digits);
  };
  const auto ticks = [&](double a, double b, bool log) {
    std::vector<double> t;
    if (log) {
      for (double v = a; v <= b + 1e-9; v += 1) {
        t.push_back(v);
        if (b - a <= 2 && v + 1 <= b + 1e-9) t.push_back(v + std::log10(2.0)), t.push_back(v + std::log10(5.0));
      }
    } else {
      const double step = nice_step(a, b);
      for (double v = a; v <= b + 1e-9 * step; v += step) t.push_back(v);
    }
    return t;
  };
  for (double v : ticks(y0, y1, p.log_y)) {
    const double y = T + (H - T - B) * (1 - (v - y0) / (y1 - y0));
    s += "<line x1=\"" + number_text(L, 1) + "\" x2=\"" + number_text(W - R, 1) + "\" y1=\"" + number_text(y, 1) +
         "\" y2=\"" + number_text(y, 1) + "\" stroke=\"#ddd\"/><text x=\"" + number_text(L - 4, 1) + "\" y=\"" +
         number_text(y + 4, 1) + "\" text-anchor=\"end\">" + tick_text(v, p.log_y, y0, y1) + "</text>\n";
  }
  for (double v : ticks(x0, x1, p.log_x)) {
    const double x = L + (W - L - R) * (v - x0) / (x1 - x0);
    s += "<line x1=\"" + number_text(x, 1) + "\" x2=\"" + number_text(x, 1) + "\" y1=\"" + number_text(T, 1) +
         "\" y2=\"" + number_text(H - B, 1) + "\" stroke=\"#eee\"/><text x=\"" + number_text(x, 1) + "\" y=\"" +
         number_text(H - B + 16, 1) + "\" text-anchor=\"middle\">" + tick_text(v, p.log_x, x0, x1) + "</text>\n";
  }
  s += "<text x=\"" + number_text((L + W - R) / 2, 1) + "\" y=\"" + number_text(H - 8, 1) + "\" text-anchor=\"middle\">" +
       html_escape(p.x_label) + "</text>\n";
  s += "<text transform=\"translate(14," + number_text((T + H - B) / 2, 1) + ") rotate(-90)\" text-anchor=\"middle\">" +
       html_escape(p.y_label) + "</text>\n";
  int legend = 0;
  for (const auto& ser : p.series) {
    std::vector<const Point*> pts;
    for (const auto& q : ser.points)
      if (usable(q)) pts.push_back(&q);
    if (ser.joined && pts.size() > 1) {
      std::vector<const Point*> sorted = pts;
      std::sort(sorted.begin(), sorted.end(), [](const Point* a, const Point* b) { return a->x < b->x; });
      s += "<polyline fill=\"none\" stroke=\"" + ser.colour + "\" stroke-width=\"1.5\" points=\"";
      for (const Point* q : sorted) s += number_text(X(q->x), 1) + "," + number_text(Y(q->y), 1) + " ";
      s += "\"/>\n";
    }
    for (const Point* q : pts) {
      if (!ser.dots) break;
      const std::string tip = html_escape(ser.name + ": " + q->label);
      std::string dot = "<circle cx=\"" + number_text(X(q->x), 1) + "\" cy=\"" + number_text(Y(q->y), 1) + "\" r=\"4\" fill=\"" +
                        ser.colour + "\"><title>" + tip + "</title></circle>";
      if (q->marked)
        dot += "<circle cx=\"" + number_text(X(q->x), 1) + "\" cy=\"" + number_text(Y(q->y), 1) +
               "\" r=\"8\" fill=\"none\" stroke=\"black\" stroke-width=\"1.5\"/>";
      s += q->job.empty() ? dot + "\n" : "<a href=\"#" + anchor(q->job) + "\">" + dot + "</a>\n";
    }
    s += (ser.dots ? "<circle cx=\"" + number_text(W - R - 190, 1) + "\" cy=\"" + number_text(T + 10 + 16 * legend, 1) +
                         "\" r=\"4\" fill=\"" + ser.colour + "\"/>"
                   : "<line x1=\"" + number_text(W - R - 196, 1) + "\" x2=\"" + number_text(W - R - 184, 1) + "\" y1=\"" +
                         number_text(T + 10 + 16 * legend, 1) + "\" y2=\"" + number_text(T + 10 + 16 * legend, 1) + "\" stroke=\"" +
                         ser.colour + "\" stroke-width=\"1.5\"/>") +
         "<text x=\"" + number_text(W - R - 180, 1) + "\" y=\"" + number_text(T + 14 + 16 * legend, 1) + "\">" +
         html_escape(ser.name) + "</text>\n";
    ++legend;
  }
  s += "</svg>\n";
  return s;
}

struct PageInfo {
  std::string suite, generated, machine_html;
  io::Json machine;
};

// Writes OUT/index.html, OUT/results.json and OUT/TABLE.csv for every table.
inline void write_page(const fs::path& out, const std::vector<Section>& sections, const Runner& runner,
                       const std::vector<Job>& jobs, const PageInfo& info) {
  fs::create_directories(out);
  io::Json results = {{"suite", info.suite}, {"generated", info.generated}, {"machine", info.machine}, {"build", runner.build()}};
  io::Json js = io::Json::array();
  for (const auto& sec : sections) {
    io::Json jsec = {{"id", sec.id}, {"title", sec.title}, {"intro", sec.intro}};
    io::Json tables = io::Json::array();
    for (const auto& t : sec.tables) {
      io::Json rows = io::Json::array();
      std::ofstream csv(out / (t.id + ".csv"));
      for (std::size_t c = 0; c < t.columns.size(); ++c) csv << (c ? "," : "") << csv_field(t.columns[c]);
      csv << "\n";
      for (const auto& row : t.rows) {
        io::Json jrow = io::Json::array();
        for (std::size_t c = 0; c < row.size(); ++c) {
          const Cell& cell = row[c];
          io::Json jc = {{"text", cell.text}};
          if (cell.value) jc["value"] = *cell.value;
          if (!cell.job.empty()) jc["run"] = cell.job;
          jrow.push_back(jc);
          csv << (c ? "," : "") << csv_field(plain_number(cell.text) && cell.value && std::isfinite(*cell.value) ? sci_text(*cell.value, 6) : cell.text);
        }
        csv << "\n";
        rows.push_back(jrow);
      }
      tables.push_back({{"id", t.id}, {"title", t.title}, {"note", t.note}, {"columns", t.columns}, {"rows", rows},
                        {"csv", t.id + ".csv"}});
    }
    io::Json plots = io::Json::array();
    for (const auto& p : sec.plots) {
      io::Json series = io::Json::array();
      for (const auto& ser : p.series) {
        io::Json pts = io::Json::array();
        for (const auto& q : ser.points)
          pts.push_back({{"x", q.x}, {"y", q.y}, {"label", q.label}, {"run", q.job}, {"marked", q.marked}});
        series.push_back({{"name", ser.name}, {"points", pts}});
      }
      plots.push_back({{"id", p.id}, {"title", p.title}, {"x", p.x_label}, {"y", p.y_label}, {"series", series}});
    }
    io::Json pics = io::Json::array();
    for (const auto& pic : sec.pictures) pics.push_back({{"file", pic.file}, {"caption", pic.caption}});
    jsec["tables"] = tables;
    jsec["plots"] = plots;
    jsec["pictures"] = pics;
    js.push_back(jsec);
  }
  results["sections"] = js;
  io::Json runs = io::Json::array();
  for (const auto& j : jobs) {
    const JobRecord* r = runner.record(j.id);
    io::Json jr = r ? r->json() : io::Json{{"id", j.id}, {"status", "not run"}};
    jr["title"] = j.title;
    runs.push_back(jr);
  }
  results["runs"] = runs;
  io::write_json(out / "results.json", results);

  std::string h;
  h += "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n"
       "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
       "<title>difftrans report: " + html_escape(info.suite) + " suite</title>\n<style>\n"
       "body{font-family:sans-serif;max-width:60rem;margin:0 auto;padding:0 .8rem;line-height:1.4;color:#222}\n"
       "h1{font-size:1.5rem}h2{font-size:1.25rem;border-bottom:1px solid #ccc;margin-top:2rem}h3{font-size:1rem}\n"
       ".scroll{overflow-x:auto}table{border-collapse:collapse;font-size:.85rem;margin:.5rem 0}\n"
       "th,td{border:1px solid #ddd;padding:.2rem .45rem;text-align:right;white-space:nowrap}th{background:#f4f4f4}\n"
       "td:first-child,th:first-child{text-align:left}a{color:#1558b0;text-decoration:none}\n"
       "td.paper{color:#666;font-style:italic}svg{width:100%;height:auto;max-width:640px;display:block}\n"
       "figure{margin:.5rem 0}figure img{max-width:100%;height:auto;image-rendering:pixelated}\n"
       "figcaption{font-size:.85rem;color:#555}.note{font-size:.85rem;color:#444}\n"
       "code{font-size:.8rem;word-break:break-all}.failed{color:#b00}nav a{margin-right:.6rem}\n"
       "</style></head><body>\n";
  h += "<h1>difftrans report: " + html_escape(info.suite) + " suite</h1>\n";
  h += "<p class=\"note\">Generated " + html_escape(info.generated) +
       " by <code>difftrans report --suite " + html_escape(info.suite) +
       "</code>. Every number links to the run that made it (its command is at the end of the page); "
       "the data are in <a href=\"results.json\">results.json</a> and a CSV file per table. "
       "<i>Italic grey</i>: a figure quoted from the paper, for comparison.</p>\n<nav>";
  for (const auto& sec : sections) h += "<a href=\"#" + sec.id + "\">" + html_escape(sec.title) + "</a> ";
  h += "<a href=\"#runs\">Runs</a></nav>\n";
  for (const auto& sec : sections) {
    h += "<section id=\"" + sec.id + "\"><h2>" + html_escape(sec.title) + "</h2>\n";
    if (!sec.intro.empty()) h += "<p>" + sec.intro + "</p>\n";
    for (const auto& t : sec.tables) {
      h += "<h3 id=\"table-" + t.id + "\">" + html_escape(t.title) + "</h3>\n<div class=\"scroll\"><table><thead><tr>";
      for (const auto& c : t.columns) h += "<th>" + html_escape(c) + "</th>";
      h += "</tr></thead><tbody>\n";
      for (const auto& row : t.rows) {
        h += "<tr>";
        for (const auto& cell : row) {
          const bool paper = cell.job == "paper";
          h += paper ? "<td class=\"paper\">" : "<td>";
          if (!cell.job.empty() && !paper)
            h += "<a href=\"#" + anchor(cell.job) + "\">" + html_escape(cell.text) + "</a>";
          else
            h += html_escape(cell.text);
          h += "</td>";
        }
        h += "</tr>\n";
      }
      h += "</tbody></table></div>\n";
      if (!t.note.empty()) h += "<p class=\"note\">" + t.note + "</p>\n";
      h += "<p class=\"note\"><a href=\"" + t.id + ".csv\">" + t.id + ".csv</a></p>\n";
    }
    for (const auto& p : sec.plots) {
      h += "<h3 id=\"plot-" + p.id + "\">" + html_escape(p.title) + "</h3>\n" + plot_svg(p);
      if (!p.note.empty()) h += "<p class=\"note\">" + p.note + "</p>\n";
    }
    for (const auto& pic : sec.pictures)
      h += "<figure><img src=\"" + html_escape(pic.file) + "\" alt=\"" + html_escape(pic.caption) + "\" loading=\"lazy\"><figcaption>" +
           html_escape(pic.caption) + "</figcaption></figure>\n";
    h += "</section>\n";
  }
  h += "<section id=\"runs\"><h2>Runs</h2>\n<p class=\"note\">Each run is one <code>difftrans</code> command, in the "
       "folder named by its id under the work folder (<code>" + html_escape(runner.work().string()) +
       "</code>); its output went to <code>ID/stdout.json</code>, its log to <code>ID/log.txt</code>. "
       "Wall and CPU seconds and peak memory are the child process's. Runs reused from an earlier report "
       "keep the figures of the time they ran.</p>\n";
  for (const auto& j : jobs) {
    const JobRecord* r = runner.record(j.id);
    h += "<div id=\"" + anchor(j.id) + "\"><h3>" + html_escape(j.title) + " <small>(" + html_escape(j.id) + ")</small></h3>";
    if (!r) {
      h += "<p class=\"failed\">not run</p></div>\n";
      continue;
    }
    h += "<p class=\"note\"><code>" + html_escape(r->command) + "</code><br>";
    if (r->status == "done")
      h += "wall " + number_text(r->wall_seconds, 1) + " s, CPU " + number_text(r->cpu_seconds, 1) + " s, peak memory " +
           number_text(r->peak_memory_mb, 0) + " MB" + (r->reused ? ", reused" : "") +
           (r->build != runner.build() ? ", <b>made by another build (" + html_escape(r->build) + ")</b>" : "");
    else
      h += "<span class=\"failed\">" + html_escape(r->status) + (r->status == "failed" ? " (exit " + std::to_string(r->exit_code) + ")" : "") +
           "</span>";
    h += "</p></div>\n";
  }
  h += "</section>\n<footer><h2>Machine</h2>" + info.machine_html + "</footer>\n</body></html>\n";
  const fs::path tmp = out / "index.html.partial";
  {
    std::ofstream f(tmp);
    f << h;
    if (!f) throw std::runtime_error("report: cannot write " + tmp.string());
  }
  fs::rename(tmp, out / "index.html");
}

}  // namespace difftrans::cli::report
