// The registry of scenario kinds: the one list to extend when adding a kind (scenario.h,
// docs/validation.md "Adding a scenario kind"). The order of the table is the order of the
// names in the message for an unknown kind.
#include "scenario.h"

namespace eco::validate {

// The factories, each defined at the end of its kind's file scenarios/<kind>.cpp.
std::unique_ptr<Scenario> createSelfThinning(const ScenarioParse& in);
std::unique_ptr<Scenario> createSuccession(const ScenarioParse& in);
std::unique_ptr<Scenario> createEquilibrium(const ScenarioParse& in);
std::unique_ptr<Scenario> createGapDynamics(const ScenarioParse& in);
std::unique_ptr<Scenario> createAbioticGradients(const ScenarioParse& in);
std::unique_ptr<Scenario> createDeussenComparison(const ScenarioParse& in);
std::unique_ptr<Scenario> createDeussenCircles(const ScenarioParse& in);
std::unique_ptr<Scenario> createFidelity(const ScenarioParse& in);
std::unique_ptr<Scenario> createEcoMod(const ScenarioParse& in);

const std::vector<ScenarioKind>& scenarioKinds() {
    static const std::vector<ScenarioKind> kinds{
        // [scenario] kind     forest scene  factory
        {"self_thinning",      false,        &createSelfThinning},
        {"succession",         true,         &createSuccession},
        {"equilibrium",        true,         &createEquilibrium},
        {"gap_dynamics",       true,         &createGapDynamics},
        {"abiotic_gradients",  true,         &createAbioticGradients},
        {"deussen_comparison", true,         &createDeussenComparison},
        {"deussen_circles",    false,        &createDeussenCircles},
        {"fidelity",           false,        &createFidelity},
        {"ecomod",             false,        &createEcoMod},
    };
    return kinds;
}

const ScenarioKind* findScenarioKind(const std::string& name) {
    for (const ScenarioKind& k : scenarioKinds())
        if (name == k.name) return &k;
    return nullptr;
}

}  // namespace eco::validate
