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

}  // namespace eco
