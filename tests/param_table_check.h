// The shared check of a parameter table (core/param_desc.h): each key has its row in the
// docs, as paramDocRow writes it; the defaults are valid; a value just outside a field's
// range is refused by the struct's validation, with the key and the rule in the message;
// and the struct's record holds each key with its value.
#pragma once

#include <catch2/catch.hpp>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "param_desc.h"
#include "test_util.h"

namespace eco::test {

/// `validate(p)` throws for an invalid p; `record(p)` gives the (key, text) pairs p is
/// recorded as, reals with `recordDigits` significant digits (empty: no string record).
template <typename S, typename Validate, typename Record>
void checkParamTable(const std::vector<ParamDesc<S>>& fields, const std::string& docsFile, Validate validate,
                     Record record, int recordDigits) {
    std::ifstream in(sourcePath(docsFile));
    REQUIRE(in);
    std::stringstream docs;
    docs << in.rdbuf();
    const S defaults{};
    REQUIRE_NOTHROW(validate(defaults));
    const std::vector<std::pair<std::string, std::string>> recorded = record(defaults);
    for (const auto& f : fields) {
        INFO(f.key);
        CHECK(docs.str().find(paramDocRow(f)) != std::string::npos);
        if (recordDigits > 0) {
            const std::pair<std::string, std::string> entry(f.key, paramText(f, defaults, recordDigits));
            CHECK(std::find(recorded.begin(), recorded.end(), entry) != recorded.end());
        }
        if (f.kind == ParamDesc<S>::Kind::Seed) continue;
        const ParamRange& r = f.range;
        if (r.lowBound == ParamRange::Bound::None && r.highBound == ParamRange::Bound::None) continue;
        const double outside = r.highBound != ParamRange::Bound::None ? r.hi + 1 : r.lo - 1;
        S p{};
        setParam(p, fields, f.key, outside, "parameter");
        CHECK_THROWS_WITH(validate(p), Catch::Contains(std::string("'") + f.key + "'") && Catch::Contains(f.ruleText()));
    }
}

}  // namespace eco::test
