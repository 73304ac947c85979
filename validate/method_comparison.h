// The placement methods side by side (issue 29 item 3, docs/synth.md "The methods compared"):
// the fidelity protocol (fidelity_protocol.h) run once per undergrowth sampler on the same
// terrain, canopy, abiotics, simulations and database (the shared stages are made once and
// reused), each scene also measured by Xu et al. 2015's enlargement evaluation
// (xu_evaluation.h) against simulation A, and the sampler's own time per million plants.
// `eco fidelity --synth-method all` (or a comma list) calls runMethodComparison.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "fidelity.h"
#include "fidelity_protocol.h"
#include "reporter.h"
#include "xu_evaluation.h"

namespace eco::validate {

/// `--synth-method`'s value as a list: "all" = every method, "a,b" = those; one name = itself.
/// ValidationError for an unknown or repeated name.
std::vector<std::string> parseMethodList(const std::string& text);

/// One method's figures.
struct MethodResult {
    std::string method;
    std::string scenePath;
    FidelityReport fidelity;
    XuEvaluation xu;                 ///< enlargements of the exemplar square (those that fit)
    std::vector<int> xuFactorsSkipped;  ///< factors whose patch is larger than the scene
    std::int64_t scenePlants = 0;    ///< undergrowth plants of the whole scene
    double samplingSeconds = 0;      ///< the sampler's wall time (scene /provenance; NaN when not recorded)
};

struct MethodComparison {
    std::vector<MethodResult> methods;
    RectWindow exemplarWindow;       ///< the square of simulation A used as Xu's exemplar
    std::string markdown, markdownPath, csvPath;
};

/// The exemplar square of Xu's evaluation: side a third of the plot's shorter side, centred
/// in the plot (so that 3 x 3 exemplars are the plot).
RectWindow xuExemplarWindow(const RectWindow& plot);

/// Xu's evaluation of a scene's undergrowth (pooled, unmarked) over `sceneWindow` against
/// the exemplar's plants inside `exemplarWindow`: the factors of {3, 6, 10} whose patch fits
/// in the scene; the others are returned in `skipped`. Bins: the fidelity bins, cut at half
/// the exemplar's side.
XuEvaluation evaluateXuEnlargements(const std::vector<Plant>& exemplar, const RectWindow& exemplarWindow,
                                    const std::vector<Plant>& scene, const RectWindow& sceneWindow,
                                    const DistanceBins& fidelityBins, std::uint64_t seed, std::vector<int>& skipped);

/// The comparison as Markdown: every overall fidelity figure per method (distance to B and
/// score, the best method marked), the per-species under-crown shares, Xu's PCT.DEV per
/// enlargement, and speed per million plants.
std::string methodComparisonMarkdown(const MethodComparison& c, const std::string& heading);
/// Every figure in long form (atomic): method,kind,quantity,value.
void writeMethodComparisonCsv(const std::string& path, const MethodComparison& c);

/// Run the protocol for each method in `methods` (stages shared and cached), measure, and
/// write OUT_DIR/methods.md and methods.csv (or options.outMd / outCsv) as one set.
MethodComparison runMethodComparison(const FidelityRunOptions& options, const std::vector<std::string>& methods,
                                     pipeline::Reporter& reporter,
                                     const std::function<std::unique_ptr<pipeline::Reporter>()>& stageReporter);

}  // namespace eco::validate
