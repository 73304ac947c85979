// Numbers in messages, tables and reports: one formatting for the whole toolkit.
#pragma once

#include <cmath>
#include <cstdlib>
#include <istream>
#include <sstream>
#include <string>
#include <vector>

#include "error.h"

namespace eco {

/// `v` with at most `significant` significant digits, as an ostream prints it (1, 0.25,
/// 1.5e-07). Messages use the default; tables and reports choose their precision.
inline std::string formatNumber(double v, int significant = 6) {
    std::ostringstream os;
    os.precision(significant);
    os << v;
    return os.str();
}

/// A CSV field (RFC 4180): as it is, or in double quotes (a quote doubled) when it holds a
/// comma, a quote or a line break.
inline std::string csvField(const std::string& s) {
    if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
    std::string out = "\"";
    for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
    return out + "\"";
}

/// Text for a Markdown table cell: each '|' escaped as "\\|", so that it does not split the cell.
inline std::string markdownCell(std::string s) {
    for (std::size_t p = 0; (p = s.find('|', p)) != std::string::npos; p += 2) s.replace(p, 1, "\\|");
    return s;
}

/// `s` without leading and trailing blanks, tabs and carriage returns.
inline std::string trimmedText(const std::string& s) {
    const auto b = s.find_first_not_of(" \t\r");
    if (b == std::string::npos) return {};
    const auto e = s.find_last_not_of(" \t\r");
    return s.substr(b, e - b + 1);
}

/// Split one CSV line into `out`; fields may be double-quoted ("" is a quote inside quotes),
/// unquoted fields are trimmed. False when a quote is not closed on the line.
inline bool splitCsvLine(const std::string& line, std::vector<std::string>& out) {
    out.clear();
    std::string field;
    bool quoted = false, wasQuoted = false;
    for (std::size_t i = 0; i < line.size(); ++i) {
        const char c = line[i];
        if (quoted) {
            if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
                field += '"';
                ++i;
            } else if (c == '"') {
                quoted = false;
            } else {
                field += c;
            }
        } else if (c == '"' && field.find_first_not_of(" \t") == std::string::npos) {
            quoted = wasQuoted = true;
            field.clear();
        } else if (c == ',') {
            out.push_back(wasQuoted ? field : trimmedText(field));
            field.clear();
            wasQuoted = false;
        } else if (c != '\r') {
            field += c;
        }
    }
    if (quoted) return false;
    out.push_back(wasQuoted ? field : trimmedText(field));
    return true;
}

/// The data rows of a CSV whose header line has been read (`lineNo` its line number, counted
/// on): blank and '#' lines are skipped, each row is split and must have `nFields` fields, and
/// row(fields, where) is called with where = "PATH:LINE: " for its messages. IoError for an
/// unterminated quote or a wrong field count.
template <typename Row>
void forEachCsvRow(std::istream& in, const std::string& path, int& lineNo, std::size_t nFields, Row&& row) {
    std::string line;
    std::vector<std::string> fields;
    while (std::getline(in, line)) {
        ++lineNo;
        const std::string t = trimmedText(line);
        if (t.empty() || t[0] == '#') continue;
        const std::string where = path + ":" + std::to_string(lineNo) + ": ";
        if (!splitCsvLine(line, fields)) throw IoError(where + "unterminated quote");
        if (fields.size() != nFields)
            throw IoError(where + "expected " + std::to_string(nFields) + " fields as in the header, found " +
                          std::to_string(fields.size()));
        row(fields, where);
    }
}

/// Field `col` of a CSV row as a finite number; IoError "WHERE column NAME: 'TEXT' is not a
/// finite number" otherwise.
inline double csvNumber(const std::vector<std::string>& fields, int col, const char* name, const std::string& where) {
    const std::string& f = fields[static_cast<std::size_t>(col)];
    char* end = nullptr;
    const double v = std::strtod(f.c_str(), &end);
    if (f.empty() || end != f.c_str() + f.size() || !std::isfinite(v))
        throw IoError(where + "column " + name + ": '" + f + "' is not a finite number");
    return v;
}

}  // namespace eco
