// Numbers in messages, tables and reports: one formatting for the whole toolkit.
#pragma once

#include <sstream>
#include <string>

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

}  // namespace eco
