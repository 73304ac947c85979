// One description per parameter (issue 23, item 5): key, one-line doc, unit and the
// allowed range, so that one table drives setting by key (TOML and flags), the attributes
// written into outputs, validation with its messages, and the documentation (a test checks
// each key's row in the docs). The tables: canopyParamFields and speciesMapParamFields
// (synth/), simParamFields (sim/sim_config.h), synthParamFields, refineParamFields and
// forestFloorParamFields (synth/), analysisParamFields (analysis/), sunParamFields and
// abioticParamFields (core/abiotics.h); the biome's species keys have a descriptor of their
// own built on ParamRange (SpeciesField, core/biome.h). The docs' tables are generated from
// these tables: eco config describe --markdown (apps/cmd_config.cpp) prints them,
// tools/param_docs.py writes them into docs/, tests/docs_cli_test.cpp checks the docs hold them.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

#include "error.h"
#include "text_format.h"

namespace eco {

/// The allowed values of a numeric parameter: an optional lower and upper bound, each
/// open or closed. Values must also be finite.
struct ParamRange {
    enum class Bound { None, Closed, Open };
    Bound lowBound = Bound::None;
    double lo = 0;
    Bound highBound = Bound::None;
    double hi = 0;

    static ParamRange any() { return {}; }
    /// v >= lo
    static ParamRange atLeast(double lo) { return {Bound::Closed, lo, Bound::None, 0}; }
    /// v > lo
    static ParamRange above(double lo) { return {Bound::Open, lo, Bound::None, 0}; }
    /// lo <= v <= hi
    static ParamRange closed(double lo, double hi) { return {Bound::Closed, lo, Bound::Closed, hi}; }
    /// lo < v <= hi
    static ParamRange openClosed(double lo, double hi) { return {Bound::Open, lo, Bound::Closed, hi}; }
    /// lo < v < hi
    static ParamRange open(double lo, double hi) { return {Bound::Open, lo, Bound::Open, hi}; }

    /// True when v is finite and within the bounds.
    bool contains(double v) const {
        if (!std::isfinite(v)) return false;
        if (lowBound == Bound::Closed && v < lo) return false;
        if (lowBound == Bound::Open && v <= lo) return false;
        if (highBound == Bound::Closed && v > hi) return false;
        if (highBound == Bound::Open && v >= hi) return false;
        return true;
    }
    /// The allowed values as documentation text: "> 0", ">= 0", "[0, 1]", "(0, 10]", or
    /// "any number" when unbounded.
    std::string valuesText() const {
        auto num = [](double v) { return formatNumber(v, 6); };
        if (highBound == Bound::None) {
            if (lowBound == Bound::Closed) return ">= " + num(lo);
            if (lowBound == Bound::Open) return "> " + num(lo);
            return "any number";
        }
        if (lowBound == Bound::None) return std::string(highBound == Bound::Closed ? "<= " : "< ") + num(hi);
        return std::string(lowBound == Bound::Closed ? "[" : "(") + num(lo) + ", " + num(hi) +
               (highBound == Bound::Closed ? "]" : ")");
    }
    /// The rule as message text: "must be >= 0", "must be > 0", "must lie in (0, 10]".
    std::string text() const {
        if (highBound == Bound::None && lowBound == Bound::None) return "must be finite";
        const bool interval = highBound != Bound::None && lowBound != Bound::None;
        return (interval ? "must lie in " : "must be ") + valuesText();
    }
};

/// One parameter of struct S: a real, an integer or a 64-bit seed member.
template <typename S>
struct ParamDesc {
    const char* key;   ///< snake_case, as in TOML configs, flags and HDF5 attributes
    const char* doc;   ///< one line, the meaning (the unit is `unit`)
    const char* unit;  ///< "m", "mm/month", "crown radii", ...; "" for a count, share or pure number
    enum class Kind { Real, Integer, Seed } kind;
    double S::*real = nullptr;
    int S::*integer = nullptr;
    ParamRange range{};               ///< allowed values (seeds: [0, 2^53))
    std::uint64_t S::*seed = nullptr;
    const char* rule = nullptr;       ///< message text of the range when not range.text()
    const char* defaultText = nullptr;  ///< the default in words when it is derived (not S{}'s value)

    /// The range as message text ("must lie in [0, 1]").
    std::string ruleText() const { return rule ? std::string(rule) : range.text(); }

    /// The value as a double (seeds above 2^53 lose precision; write them separately).
    double value(const S& p) const {
        switch (kind) {
            case Kind::Real: return p.*real;
            case Kind::Integer: return p.*integer;
            case Kind::Seed: return static_cast<double>(p.*seed);
        }
        return 0;
    }
};

/// Sets the field `key` of p from a number; ValidationError "<what> 'key' ..." for an unknown
/// key (listing the keys), a non-finite value, or a non-integer value of an integer or seed.
template <typename S>
void setParam(S& p, const std::vector<ParamDesc<S>>& fields, const std::string& key, double value, const std::string& what) {
    auto num = [](double v) { return formatNumber(v, 6); };
    using Kind = typename ParamDesc<S>::Kind;
    for (const auto& f : fields) {
        if (key != f.key) continue;
        if (!std::isfinite(value)) throw ValidationError(what + " '" + key + "' must be finite, got " + num(value));
        if (f.kind != Kind::Real && value != std::floor(value))
            throw ValidationError(what + " '" + key + "' must be an integer, got " + num(value));
        switch (f.kind) {
            case Kind::Real: p.*(f.real) = value; break;
            case Kind::Integer:
                if (std::abs(value) > 1e9) throw ValidationError(what + " '" + key + "' out of range: " + num(value));
                p.*(f.integer) = static_cast<int>(value);
                break;
            case Kind::Seed:
                if (value < 0 || value >= 9007199254740992.0)
                    throw ValidationError(what + " '" + key + "' must lie in [0, 2^53), got " + num(value));
                p.*(f.seed) = static_cast<std::uint64_t>(value);
                break;
        }
        return;
    }
    std::string keys;
    for (const auto& f : fields) keys += (keys.empty() ? "" : ", ") + std::string(f.key);
    throw ValidationError("unknown " + what + " '" + key + "' (known: " + keys + ")");
}

/// ValidationError "<what> 'key' <rule>, got <value>" for the first real or integer field
/// of p outside its range, in table order.
template <typename S>
void validateParams(const S& p, const std::vector<ParamDesc<S>>& fields, const std::string& what) {
    for (const auto& f : fields) {
        if (f.kind == ParamDesc<S>::Kind::Seed) continue;
        const double v = f.value(p);
        if (!f.range.contains(v))
            throw ValidationError(what + " '" + f.key + "' " + f.ruleText() + ", got " + formatNumber(v, 6));
    }
}

/// The value of field f of p as text, for records that store parameters as strings (scene
/// attributes, the database's /parameters): integers and seeds in full, reals with
/// `significant` digits (formatNumber).
template <typename S>
std::string paramText(const ParamDesc<S>& f, const S& p, int significant) {
    switch (f.kind) {
        case ParamDesc<S>::Kind::Real: return formatNumber(p.*(f.real), significant);
        case ParamDesc<S>::Kind::Integer: return std::to_string(p.*(f.integer));
        case ParamDesc<S>::Kind::Seed: return std::to_string(p.*(f.seed));
    }
    return {};
}

/// The field `key` of a table (a flag's help text and range come from it); std::logic_error
/// for a key the table does not have, a programming error that the CLI tests meet at start.
template <typename S>
const ParamDesc<S>& paramField(const std::vector<ParamDesc<S>>& fields, const std::string& key) {
    for (const auto& f : fields)
        if (key == f.key) return f;
    throw std::logic_error("no parameter '" + key + "' in its table");
}

/// A real as TOML text that reads back to the same double: the shortest of %.6g .. %.17g
/// that round-trips, with ".0" added to a whole number (TOML would read it as an integer).
inline std::string tomlReal(double v) {
    char buf[64];
    for (int precision = 6; precision <= 17; ++precision) {
        std::snprintf(buf, sizeof buf, "%.*g", precision, v);
        if (std::strtod(buf, nullptr) == v) break;
    }
    std::string s = buf;
    if (std::isfinite(v) && s.find_first_of(".eE") == std::string::npos) s += ".0";
    return s;
}

/// The doc line with its unit after a comma ("side of a simulation cell, m"), or alone.
template <typename S>
std::string paramDocWithUnit(const ParamDesc<S>& f) {
    return *f.unit ? std::string(f.doc) + ", " + f.unit : std::string(f.doc);
}

/// The unit as the docs' tables show it: "-" for none.
template <typename S>
std::string paramUnitText(const ParamDesc<S>& f) {
    return *f.unit ? std::string(f.unit) : std::string("-");
}

/// The fields of p as TOML lines "key = value  # doc" in table order (integers and seeds as
/// TOML integers, reals with tomlReal): `eco config defaults` prints tables with it.
template <typename S>
std::string paramTomlLines(const S& p, const std::vector<ParamDesc<S>>& fields) {
    std::string out;
    for (const auto& f : fields) {
        const std::string value = f.kind == ParamDesc<S>::Kind::Real ? tomlReal(p.*(f.real)) : paramText(f, p, 17);
        out += std::string(f.key) + " = " + value + "  # " + paramDocWithUnit(f) + "\n";
    }
    return out;
}

/// The documentation row of a field: "| `key` | default | unit | doc |" (default from S{}).
template <typename S>
std::string paramDocRow(const ParamDesc<S>& f) {
    // Static, so that every byte (padding too) is initialised: GCC warns of reading a
    // temporary's padding through a member pointer it cannot see.
    static const S defaults{};
    const std::string dflt = f.defaultText ? std::string(f.defaultText) : formatNumber(f.value(defaults), 6);
    return std::string("| `") + f.key + "` | " + dflt + " | " + paramUnitText(f) + " | " + f.doc + " |";
}

/// A command's flag and the described parameter it sets: one table per command serves both
/// the flags' declaration (apps/) and the command line a stage prints (pipeline/).
struct ParamFlagName {
    std::string flag;  ///< "--max-iterations"
    std::string key;   ///< "max_iterations"
};

/// A flag for every parameter of a table: "--" and the key with hyphens for underscores,
/// the unit suffix kept (cell_size_m: --cell-size-m), in table order.
template <typename S>
std::vector<ParamFlagName> hyphenatedParamFlags(const std::vector<ParamDesc<S>>& fields) {
    std::vector<ParamFlagName> flags;
    for (const auto& f : fields) {
        std::string flag = std::string("--") + f.key;
        for (char& c : flag)
            if (c == '_') c = '-';
        flags.push_back({flag, f.key});
    }
    return flags;
}

/// The flag of `key` in a flag table; std::logic_error when the table has none (a
/// programming error the CLI tests meet).
inline const std::string& paramFlagFor(const std::vector<ParamFlagName>& flags, const std::string& key) {
    for (const auto& f : flags)
        if (key == f.key) return f.flag;
    throw std::logic_error("no flag for parameter '" + key + "'");
}

/// Values given for some parameters of S over a base (a configuration file, else S{}), e.g.
/// by flags or a run configuration: one value per key, in the order first given. A stage's
/// options carry their parameter overrides this way instead of one optional per key, so a
/// new parameter with a flag needs no new member. Seeds are kept as 64-bit integers.
template <typename S>
class ParamOverrides {
public:
    struct Value {
        std::string key;
        double number = 0;         ///< reals and integers
        std::uint64_t seed = 0;    ///< seeds
        bool isSeed = false;
    };
    /// Set a real or integer parameter (checked against the table when applied).
    void set(const std::string& key, double value) { slot(key) = Value{key, value, 0, false}; }
    /// Set a seed parameter.
    void setSeed(const std::string& key, std::uint64_t value) { slot(key) = Value{key, 0, value, true}; }
    const Value* find(const std::string& key) const {
        for (const auto& v : values_)
            if (v.key == key) return &v;
        return nullptr;
    }
    bool empty() const { return values_.empty(); }
    const std::vector<Value>& values() const { return values_; }

    /// Apply to p in order: setParam for reals and integers (ValidationError "<what> 'key' ..."
    /// for an unknown key or a non-integer integer), seeds assigned whole. The ranges are
    /// checked afterwards by the caller's validateParams.
    void applyTo(S& p, const std::vector<ParamDesc<S>>& fields, const std::string& what) const {
        for (const auto& v : values_) {
            if (!v.isSeed) {
                setParam(p, fields, v.key, v.number, what);
                continue;
            }
            const ParamDesc<S>* seedField = nullptr;
            for (const auto& f : fields)
                if (v.key == f.key && f.kind == ParamDesc<S>::Kind::Seed) seedField = &f;
            if (!seedField) throw ValidationError("unknown seed " + what + " '" + v.key + "'");
            p.*(seedField->seed) = v.seed;
        }
    }

private:
    Value& slot(const std::string& key) {
        for (auto& v : values_)
            if (v.key == key) return v;
        return values_.emplace_back();
    }
    std::vector<Value> values_;
};

}  // namespace eco
