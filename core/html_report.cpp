#include "html_report.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <utility>

#include "atomic_file.h"
#include "image_out.h"
#include "text_format.h"

namespace eco::html {

// The page's style sheet and scripts (core/html_report_assets.cpp; hand-written, no
// libraries, no network).
namespace assets {
extern const char* const kStyle;
extern const char* const kErrorTrap;
extern const char* const kScript;
}  // namespace assets

namespace {

constexpr const char* kBase64Alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// A number for JSON: shortest round-trip-enough text, null for NaN and infinities.
std::string jsonNumber(double v) {
    if (!std::isfinite(v)) return "null";
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.7g", v);
    return buf;
}

std::string jsonNumbers(const std::vector<double>& v) {
    std::string out = "[";
    for (std::size_t i = 0; i < v.size(); ++i) out += (i ? "," : "") + jsonNumber(v[i]);
    return out + "]";
}

/// Little-endian bytes of 16-bit values (the page reads them as a Uint16Array: every browser
/// runs little-endian).
template <class T>
std::string base64OfValues(const std::vector<T>& values) {
    std::vector<std::uint8_t> bytes;
    bytes.reserve(values.size() * sizeof(T));
    for (T v : values)
        for (std::size_t b = 0; b < sizeof(T); ++b) bytes.push_back(static_cast<std::uint8_t>((static_cast<std::uint64_t>(v) >> (8 * b)) & 0xff));
    return base64(bytes.data(), bytes.size());
}

std::uint16_t quantize(double v, double lo, double hi) {
    if (!(hi > lo)) return 0;
    const double t = std::clamp((v - lo) / (hi - lo), 0.0, 1.0);
    return static_cast<std::uint16_t>(std::lround(t * 65535.0));
}

std::uint16_t centimetres(double m) { return static_cast<std::uint16_t>(std::clamp(std::lround(m * 100.0), 0L, 65535L)); }

/// Inline Markdown on escaped text: `code`, **bold**, *italic*.
std::string inlineMarkdown(const std::string& text) {
    std::string out;
    const std::string esc = escape(text);
    std::size_t i = 0;
    bool bold = false, italic = false;
    while (i < esc.size()) {
        if (esc[i] == '`') {
            const std::size_t end = esc.find('`', i + 1);
            if (end != std::string::npos) {
                out += "<code>" + esc.substr(i + 1, end - i - 1) + "</code>";
                i = end + 1;
                continue;
            }
        }
        if (esc.compare(i, 2, "**") == 0) {
            out += bold ? "</strong>" : "<strong>";
            bold = !bold;
            i += 2;
            continue;
        }
        if (esc[i] == '*' && (italic || (i + 1 < esc.size() && esc[i + 1] != ' '))) {
            out += italic ? "</em>" : "<em>";
            italic = !italic;
            ++i;
            continue;
        }
        if (esc[i] == '\\' && i + 1 < esc.size() && esc[i + 1] == '|') {  // an escaped table bar
            out += '|';
            i += 2;
            continue;
        }
        out += esc[i++];
    }
    if (italic) out += "</em>";
    if (bold) out += "</strong>";
    return out;
}

/// The cells of a Markdown table row ("| a | b \| c |"), trimmed; '\|' stays inside a cell.
std::vector<std::string> tableCells(const std::string& line) {
    std::vector<std::string> cells;
    std::string t = trimmedText(line);
    if (!t.empty() && t.front() == '|') t.erase(0, 1);
    if (t.size() >= 2 && t.back() == '|' && t[t.size() - 2] != '\\') t.pop_back();
    else if (t.size() == 1 && t.back() == '|') t.pop_back();
    std::string cell;
    for (std::size_t i = 0; i < t.size(); ++i) {
        if (t[i] == '\\' && i + 1 < t.size() && t[i + 1] == '|') {
            cell += "\\|";
            ++i;
        } else if (t[i] == '|') {
            cells.push_back(trimmedText(cell));
            cell.clear();
        } else {
            cell += t[i];
        }
    }
    cells.push_back(trimmedText(cell));
    return cells;
}

bool isSeparatorRow(const std::vector<std::string>& cells) {
    for (const auto& c : cells)
        if (c.empty() || c.find_first_not_of(":- ") != std::string::npos || c.find('-') == std::string::npos) return false;
    return !cells.empty();
}

}  // namespace

std::string escape(const std::string& text) {
    std::string out;
    out.reserve(text.size());
    for (char c : text) {
        switch (c) {
            case '&': out += "&amp;"; break;
            case '<': out += "&lt;"; break;
            case '>': out += "&gt;"; break;
            case '"': out += "&quot;"; break;
            case '\'': out += "&#39;"; break;
            default: out += c;
        }
    }
    return out;
}

std::string base64(const void* data, std::size_t size) {
    const auto* p = static_cast<const std::uint8_t*>(data);
    std::string out;
    out.reserve((size + 2) / 3 * 4);
    std::size_t i = 0;
    for (; i + 3 <= size; i += 3) {
        const std::uint32_t v = (std::uint32_t(p[i]) << 16) | (std::uint32_t(p[i + 1]) << 8) | p[i + 2];
        out += kBase64Alphabet[(v >> 18) & 63];
        out += kBase64Alphabet[(v >> 12) & 63];
        out += kBase64Alphabet[(v >> 6) & 63];
        out += kBase64Alphabet[v & 63];
    }
    if (size - i == 1) {
        const std::uint32_t v = std::uint32_t(p[i]) << 16;
        out += kBase64Alphabet[(v >> 18) & 63];
        out += kBase64Alphabet[(v >> 12) & 63];
        out += "==";
    } else if (size - i == 2) {
        const std::uint32_t v = (std::uint32_t(p[i]) << 16) | (std::uint32_t(p[i + 1]) << 8);
        out += kBase64Alphabet[(v >> 18) & 63];
        out += kBase64Alphabet[(v >> 12) & 63];
        out += kBase64Alphabet[(v >> 6) & 63];
        out += '=';
    }
    return out;
}

std::vector<std::uint8_t> base64Decode(const std::string& text) {
    std::vector<std::uint8_t> out;
    std::uint32_t acc = 0;
    int bits = 0;
    for (char c : text) {
        const char* at = c == '\0' ? nullptr : std::strchr(kBase64Alphabet, c);
        if (at == nullptr) continue;
        acc = (acc << 6) | static_cast<std::uint32_t>(at - kBase64Alphabet);
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            out.push_back(static_cast<std::uint8_t>((acc >> bits) & 0xff));
        }
    }
    return out;
}

std::string dataUriOfFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return "";
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!in.good() && !in.eof()) return "";
    std::string ext = path.substr(path.find_last_of('.') + 1);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    const std::string type = ext == "jpg" || ext == "jpeg" ? "image/jpeg" : ext == "svg" ? "image/svg+xml" : "image/png";
    return "data:" + type + ";base64," + base64(bytes.data(), bytes.size());
}

std::string jsonString(const std::string& text) {
    std::string out = "\"";
    for (unsigned char c : text) {
        switch (c) {
            case '"': out += "\\\""; break;
            case '\\': out += "\\\\"; break;
            case '\n': out += "\\n"; break;
            case '\r': out += "\\r"; break;
            case '\t': out += "\\t"; break;
            case '<': out += "\\u003c"; break;
            case '>': out += "\\u003e"; break;
            case '&': out += "\\u0026"; break;
            default:
                if (c < 0x20) {
                    char buf[8];
                    std::snprintf(buf, sizeof buf, "\\u%04x", c);
                    out += buf;
                } else {
                    out += static_cast<char>(c);
                }
        }
    }
    return out + "\"";
}

std::string categoryHex(int i) {
    const Rgb c = categoryColour(i);
    char buf[8];
    std::snprintf(buf, sizeof buf, "#%02x%02x%02x", static_cast<int>(std::lround(c[0] * 255)),
                  static_cast<int>(std::lround(c[1] * 255)), static_cast<int>(std::lround(c[2] * 255)));
    return buf;
}

Document::Document(std::string title) : title_(std::move(title)) {}

void Document::heading(int level, const std::string& text) {
    const std::string h = "h" + std::to_string(std::clamp(level, 1, 6));
    body_ += "<" + h + ">" + escape(text) + "</" + h + ">\n";
}

void Document::paragraph(const std::string& text) { body_ += "<p>" + escape(text) + "</p>\n"; }

void Document::raw(const std::string& markup) { body_ += markup; }

void Document::table(const std::vector<std::string>& header, const std::vector<std::vector<std::string>>& rows,
                     const std::vector<bool>& numeric) {
    const auto cls = [&](std::size_t c) { return c < numeric.size() && numeric[c] ? " class=\"num\"" : ""; };
    std::string t = "<div class=\"table-wrap\"><table>\n<thead><tr>";
    for (std::size_t c = 0; c < header.size(); ++c) t += std::string("<th") + cls(c) + ">" + escape(header[c]) + "</th>";
    t += "</tr></thead>\n<tbody>\n";
    for (const auto& row : rows) {
        t += "<tr>";
        for (std::size_t c = 0; c < row.size(); ++c) t += std::string("<td") + cls(c) + ">" + escape(row[c]) + "</td>";
        t += "</tr>\n";
    }
    body_ += t + "</tbody></table></div>\n";
}

void Document::picture(const std::string& path, const std::string& caption) {
    const std::string uri = dataUriOfFile(path);
    if (uri.empty()) return;
    body_ += "<figure><img src=\"" + uri + "\" alt=\"" + escape(caption) + "\"><figcaption>" + escape(caption) +
             "</figcaption></figure>\n";
}

void Document::preformatted(const std::string& text) { body_ += "<pre>" + escape(text) + "</pre>\n"; }

void Document::markdown(const std::string& text, const std::string& baseDir) {
    std::istringstream in(text);
    std::vector<std::string> lines;
    for (std::string line; std::getline(in, line);) {
        if (!line.empty() && line.back() == '\r') line.pop_back();
        lines.push_back(line);
    }
    std::string paragraphText;
    const auto flush = [&] {
        if (!trimmedText(paragraphText).empty()) body_ += "<p>" + inlineMarkdown(trimmedText(paragraphText)) + "</p>\n";
        paragraphText.clear();
    };
    for (std::size_t i = 0; i < lines.size(); ++i) {
        const std::string t = trimmedText(lines[i]);
        if (t.rfind("```", 0) == 0) {  // fenced code up to the closing fence
            flush();
            std::string code;
            for (++i; i < lines.size() && trimmedText(lines[i]).rfind("```", 0) != 0; ++i) code += lines[i] + "\n";
            preformatted(code);
            continue;
        }
        if (t.empty()) {
            flush();
            continue;
        }
        if (t[0] == '#') {
            const std::size_t level = t.find_first_not_of('#');
            if (level != std::string::npos && t[level] == ' ') {
                flush();
                const std::string h = "h" + std::to_string(std::min<std::size_t>(level, 6));  // level = the number of '#'
                body_ += "<" + h + ">" + inlineMarkdown(t.substr(level + 1)) + "</" + h + ">\n";
                continue;
            }
        }
        if (t[0] == '|') {  // a pipe table: header, separator, rows
            flush();
            std::vector<std::vector<std::string>> rows;
            for (; i < lines.size() && !trimmedText(lines[i]).empty() && trimmedText(lines[i])[0] == '|'; ++i)
                rows.push_back(tableCells(lines[i]));
            --i;
            std::vector<bool> right;
            std::size_t first = 1;
            if (rows.size() >= 2 && isSeparatorRow(rows[1])) {
                for (const auto& c : rows[1]) right.push_back(c.size() > 1 && c.back() == ':' && c.front() != ':');
                first = 2;
            }
            const auto cls = [&](std::size_t c) { return c < right.size() && right[c] ? " class=\"num\"" : ""; };
            std::string tb = "<div class=\"table-wrap\"><table>\n<thead><tr>";
            for (std::size_t c = 0; c < rows[0].size(); ++c) tb += std::string("<th") + cls(c) + ">" + inlineMarkdown(rows[0][c]) + "</th>";
            tb += "</tr></thead>\n<tbody>\n";
            for (std::size_t r = first; r < rows.size(); ++r) {
                tb += "<tr>";
                for (std::size_t c = 0; c < rows[r].size(); ++c)
                    tb += std::string("<td") + cls(c) + ">" + inlineMarkdown(rows[r][c]) + "</td>";
                tb += "</tr>\n";
            }
            body_ += tb + "</tbody></table></div>\n";
            continue;
        }
        if (t.rfind("![", 0) == 0 && t.back() == ')') {  // a picture alone on its line
            const std::size_t close = t.find("](");
            if (close != std::string::npos) {
                flush();
                const std::string caption = t.substr(2, close - 2), rel = t.substr(close + 2, t.size() - close - 3);
                picture(baseDir.empty() ? rel : baseDir + "/" + rel, caption);
                continue;
            }
        }
        if (t.rfind("- ", 0) == 0) {  // a list up to the first line that is not an item
            flush();
            std::string list = "<ul>\n";
            for (; i < lines.size() && trimmedText(lines[i]).rfind("- ", 0) == 0; ++i)
                list += "<li>" + inlineMarkdown(trimmedText(lines[i]).substr(2)) + "</li>\n";
            --i;
            body_ += list + "</ul>\n";
            continue;
        }
        paragraphText += t + " ";
    }
    flush();
}

void Document::linePlot(const LinePlot& plot) {
    std::string json = "{\"title\":" + jsonString(plot.title) + ",\"xLabel\":" + jsonString(plot.xLabel) +
                       ",\"yLabel\":" + jsonString(plot.yLabel) + ",\"logYToggle\":" + (plot.logYToggle ? "true" : "false");
    if (plot.hasReferenceY)
        json += ",\"referenceY\":" + jsonNumber(plot.referenceY) + ",\"referenceLabel\":" + jsonString(plot.referenceLabel);
    json += ",\"groups\":[";
    for (std::size_t g = 0; g < plot.groups.size(); ++g) {
        const SeriesGroup& group = plot.groups[g];
        json += std::string(g ? "," : "") + "{\"name\":" + jsonString(group.name) + ",\"series\":[";
        for (std::size_t s = 0; s < group.series.size(); ++s) {
            const Series& se = group.series[s];
            json += std::string(s ? "," : "") + "{\"name\":" + jsonString(se.name) + ",\"colour\":" +
                    jsonString(se.colour.empty() ? categoryHex(static_cast<int>(s)) : se.colour) +
                    ",\"dashed\":" + (se.dashed ? "true" : "false") + ",\"x\":" + jsonNumbers(se.x) +
                    ",\"y\":" + jsonNumbers(se.y) + "}";
        }
        json += "]}";
    }
    json += "]}";
    body_ += "<div class=\"eco-plot\" id=\"eco-plot-" + std::to_string(nextId_++) +
             "\"><script type=\"application/json\">" + json + "</script></div>\n";
}

void Document::sceneView(const SceneView& scene) {
    // Plants as compact little-endian arrays, base64: x and y quantized to 16 bits over the
    // rectangle (a 500 m scene: 8 mm steps), crown radius and height in cm, species as a byte;
    // the undergrowth first, then the canopy.
    const std::size_t n = scene.undergrowth.size() + scene.canopy.size();
    // The quantization rectangle holds every plant (a canopy tree may stand outside the
    // rectangle shown and reach into it).
    double qx0 = scene.x0M, qy0 = scene.y0M, qx1 = scene.x1M, qy1 = scene.y1M;
    for (const auto* layer : {&scene.undergrowth, &scene.canopy})
        for (const Plant& p : *layer)
            if (std::isfinite(p.xM) && std::isfinite(p.yM)) {
                qx0 = std::min(qx0, p.xM), qx1 = std::max(qx1, p.xM);
                qy0 = std::min(qy0, p.yM), qy1 = std::max(qy1, p.yM);
            }
    std::vector<std::uint16_t> qx, qy, radiusCm, heightCm;
    std::vector<std::uint8_t> species;
    qx.reserve(n), qy.reserve(n), radiusCm.reserve(n), heightCm.reserve(n), species.reserve(n);
    for (const auto* layer : {&scene.undergrowth, &scene.canopy})
        for (const Plant& p : *layer) {
            qx.push_back(quantize(p.xM, qx0, qx1));
            qy.push_back(quantize(p.yM, qy0, qy1));
            radiusCm.push_back(centimetres(p.crownRadiusM));
            heightCm.push_back(centimetres(p.heightM));
            species.push_back(static_cast<std::uint8_t>(std::clamp(p.speciesId, 0, 255)));
        }
    std::string json = "{\"title\":" + jsonString(scene.title) + ",\"x0\":" + jsonNumber(scene.x0M) +
                       ",\"y0\":" + jsonNumber(scene.y0M) + ",\"x1\":" + jsonNumber(scene.x1M) +
                       ",\"y1\":" + jsonNumber(scene.y1M) + ",\"qx0\":" + jsonNumber(qx0) + ",\"qy0\":" + jsonNumber(qy0) +
                       ",\"qx1\":" + jsonNumber(qx1) + ",\"qy1\":" + jsonNumber(qy1) + ",\"n\":" + std::to_string(n) +
                       ",\"nCanopy\":" + std::to_string(scene.canopy.size()) + ",\"species\":[";
    for (std::size_t s = 0; s < scene.speciesNames.size(); ++s)
        json += std::string(s ? "," : "") + "{\"name\":" + jsonString(scene.speciesNames[s]) +
                ",\"colour\":" + jsonString(categoryHex(static_cast<int>(s))) + "}";
    json += "],\"x\":\"" + base64OfValues(qx) + "\",\"y\":\"" + base64OfValues(qy) + "\",\"r\":\"" +
            base64OfValues(radiusCm) + "\",\"h\":\"" + base64OfValues(heightCm) + "\",\"s\":\"" +
            base64(species.data(), species.size()) + "\"}";
    body_ += "<div class=\"eco-scene\" id=\"eco-scene-" + std::to_string(nextId_++) +
             "\"><script type=\"application/json\">" + json + "</script></div>\n";
}

SceneView plotView(std::string title, double x0M, double y0M, double x1M, double y1M, std::vector<std::string> speciesNames,
                   const std::vector<Plant>& canopy, std::vector<Plant> undergrowth) {
    SceneView view;
    view.title = std::move(title);
    view.speciesNames = std::move(speciesNames);
    view.undergrowth = std::move(undergrowth);
    if (!(x1M > x0M && y1M > y0M)) {
        x0M = y0M = std::numeric_limits<double>::infinity();
        x1M = y1M = -x0M;
        for (const std::vector<Plant>* layer : {&canopy, &std::as_const(view.undergrowth)})
            for (const Plant& p : *layer) {
                x0M = std::min(x0M, p.xM), x1M = std::max(x1M, p.xM);
                y0M = std::min(y0M, p.yM), y1M = std::max(y1M, p.yM);
            }
        if (!(x0M <= x1M)) x0M = y0M = 0, x1M = y1M = 1;
    }
    view.x0M = x0M, view.y0M = y0M, view.x1M = x1M, view.y1M = y1M;
    for (const Plant& p : canopy)
        if (p.xM + p.crownRadiusM >= x0M && p.xM - p.crownRadiusM <= x1M && p.yM + p.crownRadiusM >= y0M &&
            p.yM - p.crownRadiusM <= y1M)
            view.canopy.push_back(p);
    return view;
}

std::string Document::str() const {
    return "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
           "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>" +
           escape(title_) + "</title>\n<style>" + assets::kStyle + "</style>\n<script>" + assets::kErrorTrap + "</script>\n</head>\n<body>\n" +
           body_ + "<script>" + assets::kScript + "</script>\n</body>\n</html>\n";
}

void writeDocument(const std::string& path, const Document& doc) { writeTextFile(path, doc.str()); }

}  // namespace eco::html
