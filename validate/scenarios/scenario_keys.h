// A scenario kind's own numeric keys described once (issue 23 item 5): each kind gives a
// ParamDesc table (core/param_desc.h) per TOML table it reads, and that one description
// drives reading (every key required, typed and ranged, messages naming the file, line,
// table, key and value) and the generated table of docs/validation.md
// (eco config describe --markdown validate-KIND, ScenarioKind::keys). Keys that are not
// numbers (species names, the fidelity plot window, canopy fractions) and checks between
// keys stay in the kind's reader.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "param_desc.h"
#include "scenario.h"
#include "strict_toml.h"

namespace eco::validate {

/// Reads every key of `fields` from s into p, each required, in table order: reals as
/// numbers, integers as TOML integers, seeds as non-negative TOML integers, each checked
/// against its range as it is read ("value 0 outside [1, 64]" for a closed range, else
/// the descriptor's rule: "value -1 must be positive").
template <typename S>
void readScenarioParams(StrictTable& s, S& p, const std::vector<ParamDesc<S>>& fields) {
    using Kind = typename ParamDesc<S>::Kind;
    for (const auto& f : fields) {
        const ParamRange& r = f.range;
        const bool closed = r.lowBound == ParamRange::Bound::Closed && r.highBound == ParamRange::Bound::Closed;
        switch (f.kind) {
            case Kind::Real: {
                const double v = s.number(f.key);
                if (!r.contains(v))
                    s.fail(f.key, "value " + StrictTable::fmt(v) +
                                      (closed ? " outside [" + StrictTable::fmt(r.lo) + ", " + StrictTable::fmt(r.hi) + "]"
                                              : " " + f.ruleText()));
                p.*(f.real) = v;
                break;
            }
            case Kind::Integer: {
                const std::int64_t v = s.integer(f.key);
                if (!r.contains(static_cast<double>(v)) || v < -2147483647 || v > 2147483647)
                    s.fail(f.key, "value " + std::to_string(v) +
                                      (closed ? " outside [" + std::to_string(static_cast<std::int64_t>(r.lo)) + ", " +
                                                    std::to_string(static_cast<std::int64_t>(r.hi)) + "]"
                                              : " " + f.ruleText()));
                p.*(f.integer) = static_cast<int>(v);
                break;
            }
            case Kind::Seed: {
                const std::int64_t v = s.integer(f.key);
                if (v < 0) s.fail(f.key, "value " + std::to_string(v) + " must not be negative");
                p.*(f.seed) = static_cast<std::uint64_t>(v);
                break;
            }
        }
    }
}

/// The docs rows of the keys of one table of a kind, `table` as the docs name it
/// ("[circles]", "[quick], [full]").
template <typename S>
std::vector<ScenarioKeyDoc> scenarioKeyDocs(const std::string& table, const std::vector<ParamDesc<S>>& fields) {
    std::vector<ScenarioKeyDoc> out;
    for (const auto& f : fields) {
        std::string allowed;
        switch (f.kind) {
            case ParamDesc<S>::Kind::Real: allowed = f.range.valuesText(); break;
            case ParamDesc<S>::Kind::Integer: allowed = "integer, " + f.range.valuesText(); break;
            case ParamDesc<S>::Kind::Seed: allowed = "integer, >= 0"; break;
        }
        out.push_back({table, f.key, paramUnitText(f), f.doc, allowed});
    }
    return out;
}

/// The rows of several tables, in order.
inline std::vector<ScenarioKeyDoc> joinKeyDocs(std::vector<std::vector<ScenarioKeyDoc>> parts) {
    std::vector<ScenarioKeyDoc> out;
    for (auto& p : parts) out.insert(out.end(), p.begin(), p.end());
    return out;
}

}  // namespace eco::validate
