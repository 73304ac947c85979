// Strict reading of TOML tables for biome files and run configurations: every key must be
// consumed (unknown keys are errors), every value typed and ranged, and every message names
// the file and line, the context (e.g. species 'Toyon' or [canopy]) and the key.
#pragma once

#include <toml++/toml.h>

#include <cmath>
#include <cstdint>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "error.h"
#include "param_desc.h"
#include "text_format.h"

namespace eco {

/// Reads one TOML table strictly: every key must be consumed, every value typed and ranged.
/// Messages name the file, the context (e.g. species 'Toyon'), the key and its line.
class StrictTable {
public:
    StrictTable(const toml::table& t, std::string file, std::string context)
        : t_(t), file_(std::move(file)), context_(std::move(context)) {}

    [[noreturn]] void fail(const std::string& key, const std::string& what) const {
        std::string loc = file_;
        if (const toml::node* n = t_.get(key)) {
            if (n->source().begin.line > 0) loc += ":" + std::to_string(n->source().begin.line);
        } else if (t_.source().begin.line > 0) {
            loc += ":" + std::to_string(t_.source().begin.line);
        }
        throw ValidationError(loc + ": " + context_ + (context_.empty() ? "" : ": ") + "field '" + key +
                              "': " + what);
    }

    const toml::node& node(const std::string& key) {
        used_.insert(key);
        const toml::node* n = t_.get(key);
        if (!n) fail(key, "missing");
        return *n;
    }
    bool has(const std::string& key) const { return t_.contains(key); }

    // Optional keys: the default when absent, the same checks when present.
    double numberOr(const std::string& key, double fallback) { return has(key) ? number(key) : fallback; }
    double positiveOr(const std::string& key, double fallback) { return has(key) ? positive(key) : fallback; }
    double numberInOr(const std::string& key, double lo, double hi, double fallback) {
        return has(key) ? numberIn(key, lo, hi) : fallback;
    }
    std::int64_t integerOr(const std::string& key, std::int64_t fallback) { return has(key) ? integer(key) : fallback; }
    std::string stringOr(const std::string& key, const std::string& fallback) { return has(key) ? string(key) : fallback; }
    bool booleanOr(const std::string& key, bool fallback) { return has(key) ? boolean(key) : fallback; }
    /// Like stringOr, but an empty string is a valid value (e.g. "" = "none" in run configs).
    std::string possiblyEmptyStringOr(const std::string& key, const std::string& fallback) {
        if (!has(key)) return fallback;
        auto s = node(key).value_exact<std::string>();
        if (!s) fail(key, "expected a string");
        return *s;
    }
    /// A sub-table, or nullptr when absent (an error when present but not a table).
    const toml::table* optionalTable(const std::string& key) { return has(key) ? &table(key) : nullptr; }
    const std::string& file() const { return file_; }
    const std::string& context() const { return context_; }

    double number(const std::string& key) {
        const toml::node& n = node(key);
        double v;
        if (auto f = n.value_exact<double>()) v = *f;
        else if (auto i = n.value_exact<std::int64_t>()) v = static_cast<double>(*i);
        else fail(key, "expected a number");
        if (!std::isfinite(v)) fail(key, "value is not finite");
        return v;
    }
    double numberIn(const std::string& key, double lo, double hi) {
        const double v = number(key);
        if (v < lo || v > hi) fail(key, "value " + fmt(v) + " outside [" + fmt(lo) + ", " + fmt(hi) + "]");
        return v;
    }
    double positive(const std::string& key) {
        const double v = number(key);
        if (!(v > 0)) fail(key, "value " + fmt(v) + " must be positive");
        return v;
    }
    std::int64_t integer(const std::string& key) {
        const toml::node& n = node(key);
        auto i = n.value_exact<std::int64_t>();
        if (!i) fail(key, "expected an integer");
        return *i;
    }
    std::string string(const std::string& key) {
        const toml::node& n = node(key);
        auto s = n.value_exact<std::string>();
        if (!s) fail(key, "expected a string");
        if (s->empty()) fail(key, "must not be empty");
        return *s;
    }
    bool boolean(const std::string& key) {
        auto b = node(key).value_exact<bool>();
        if (!b) fail(key, "expected true or false");
        return *b;
    }
    const toml::table& table(const std::string& key) {
        const toml::table* t = node(key).as_table();
        if (!t) fail(key, "expected a table");
        return *t;
    }
    const toml::array& array(const std::string& key) {
        const toml::array* a = node(key).as_array();
        if (!a) fail(key, "expected an array");
        return *a;
    }
    std::vector<double> numbers(const std::string& key, std::size_t expectCount) {
        const toml::array& a = array(key);
        if (a.size() != expectCount)
            fail(key, "expected " + std::to_string(expectCount) + " values, got " + std::to_string(a.size()));
        std::vector<double> out;
        for (const auto& e : a) {
            if (auto f = e.value_exact<double>()) out.push_back(*f);
            else if (auto i = e.value_exact<std::int64_t>()) out.push_back(static_cast<double>(*i));
            else fail(key, "element " + std::to_string(out.size()) + " is not a number");
            if (!std::isfinite(out.back())) fail(key, "element " + std::to_string(out.size() - 1) + " is not finite");
        }
        return out;
    }
    std::vector<std::int64_t> integers(const std::string& key) {
        std::vector<std::int64_t> out;
        for (const auto& e : array(key)) {
            auto i = e.value_exact<std::int64_t>();
            if (!i) fail(key, "element " + std::to_string(out.size()) + " is not an integer");
            out.push_back(*i);
        }
        return out;
    }
    std::vector<std::string> strings(const std::string& key) {
        std::vector<std::string> out;
        for (const auto& e : array(key)) {
            auto s = e.value_exact<std::string>();
            if (!s) fail(key, "element " + std::to_string(out.size()) + " is not a string");
            out.push_back(*s);
        }
        return out;
    }
    /// Unknown keys are errors (a typo must not silently fall back to a default).
    void finish() const {
        for (const auto& [k, v] : t_)
            if (!used_.count(std::string(k.str()))) fail(std::string(k.str()), "unknown key");
    }

    static std::string fmt(double v) { return formatNumber(v); }

private:
    const toml::table& t_;
    std::string file_;
    std::string context_;
    std::set<std::string> used_;
};

/// Reads the keys of `fields` that table t has into p (absent keys keep p's values): reals
/// as numbers, integers as TOML integers within int's range, seeds as non-negative
/// integers. Ranges are left to validateParams, which the caller runs on the whole struct.
template <typename S>
void readParams(StrictTable& t, S& p, const std::vector<ParamDesc<S>>& fields);

/// Reads the key of one field into p when table t has it (readParams' rule for one field).
/// Returns whether t had it.
template <typename S>
bool readParam(StrictTable& t, S& p, const ParamDesc<S>& f);

/// Every (real) field of `fields` required, each checked against its range as it is read,
/// so that the message names the file, the line, the table and the key (the biome's
/// [climate], [soil] and [vigour] tables).
template <typename S>
void readRequiredParams(StrictTable& t, S& p, const std::vector<ParamDesc<S>>& fields) {
    for (const auto& f : fields) {
        const double v = t.number(f.key);
        if (!f.range.contains(v)) t.fail(f.key, "value " + StrictTable::fmt(v) + " " + f.ruleText());
        p.*(f.real) = v;
    }
}

template <typename S>
bool readParam(StrictTable& t, S& p, const ParamDesc<S>& f) {
    if (!t.has(f.key)) return false;
    switch (f.kind) {
        case ParamDesc<S>::Kind::Real: p.*(f.real) = t.number(f.key); break;
        case ParamDesc<S>::Kind::Integer: {
            const std::int64_t v = t.integer(f.key);
            if (v < -2147483647 || v > 2147483647) t.fail(f.key, "value " + std::to_string(v) + " out of range");
            p.*(f.integer) = static_cast<int>(v);
            break;
        }
        case ParamDesc<S>::Kind::Seed: {
            const std::int64_t v = t.integer(f.key);
            if (v < 0) t.fail(f.key, "must be >= 0");
            p.*(f.seed) = static_cast<std::uint64_t>(v);
            break;
        }
    }
    return true;
}

template <typename S>
void readParams(StrictTable& t, S& p, const std::vector<ParamDesc<S>>& fields) {
    for (const auto& f : fields) readParam(t, p, f);
}

/// A path written in the configuration file `configPath`, as the program opens it: relative
/// paths are relative to the directory of that file (so a configuration works from any
/// working directory); absolute paths and "" are returned unchanged. The result is lexically
/// normalised ("configs/../out/demo" -> "out/demo"). `configPath` without a directory (a file
/// in the working directory) leaves `value` as it is.
std::string pathRelativeToConfig(const std::string& configPath, const std::string& value);

/// Rewrites the path-valued keys `pathKeys` ({table, key}; table "" = the root) of a
/// configuration read from `configPath` as absolute paths (relative ones resolved as
/// pathRelativeToConfig does, then made absolute): for a configuration that is copied into
/// another directory (an ensemble member's member.toml), where its own directory is lost.
void absolutizeConfigPaths(toml::table& config, const std::string& configPath,
                           const std::vector<std::pair<std::string, std::string>>& pathKeys);

/// Parse TOML text; IoError "<source>:<line>: invalid TOML: ..." on a syntax error.
toml::table parseTomlText(const std::string& text, const std::string& sourceName);
/// Read and parse a TOML file; IoError naming the file when missing or invalid.
toml::table parseTomlFile(const std::string& path);

}  // namespace eco
