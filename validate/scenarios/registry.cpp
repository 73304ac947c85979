// The registry of scenario kinds: the one list to extend when adding a kind (scenario.h,
// docs/validation.md "Adding a scenario kind"). The order of the table is the order of the
// names in the message for an unknown kind.
#include "scenario.h"

namespace eco::validate {

// The factories and the described keys, each defined at the end of its kind's file scenarios/<kind>.cpp.
std::unique_ptr<Scenario> createSelfThinning(const ScenarioParse& in);
std::vector<ScenarioKeyDoc> selfThinningKeys();
std::unique_ptr<Scenario> createSuccession(const ScenarioParse& in);
std::vector<ScenarioKeyDoc> successionKeys();
std::unique_ptr<Scenario> createEquilibrium(const ScenarioParse& in);
std::vector<ScenarioKeyDoc> equilibriumKeys();
std::unique_ptr<Scenario> createGapDynamics(const ScenarioParse& in);
std::vector<ScenarioKeyDoc> gapDynamicsKeys();
std::unique_ptr<Scenario> createAbioticGradients(const ScenarioParse& in);
std::vector<ScenarioKeyDoc> abioticGradientsKeys();
std::unique_ptr<Scenario> createDeussenComparison(const ScenarioParse& in);
std::vector<ScenarioKeyDoc> deussenComparisonKeys();
std::unique_ptr<Scenario> createDeussenCircles(const ScenarioParse& in);
std::vector<ScenarioKeyDoc> deussenCirclesKeys();
std::unique_ptr<Scenario> createFidelity(const ScenarioParse& in);
std::vector<ScenarioKeyDoc> fidelityKeys();
std::unique_ptr<Scenario> createEcoMod(const ScenarioParse& in);
std::vector<ScenarioKeyDoc> ecomodKeys();

const std::vector<ScenarioKind>& scenarioKinds() {
    static const std::vector<ScenarioKind> kinds{
        // [scenario] kind     forest scene  factory                   keys
        {"self_thinning",      false,        &createSelfThinning,      &selfThinningKeys},
        {"succession",         true,         &createSuccession,        &successionKeys},
        {"equilibrium",        true,         &createEquilibrium,       &equilibriumKeys},
        {"gap_dynamics",       true,         &createGapDynamics,       &gapDynamicsKeys},
        {"abiotic_gradients",  true,         &createAbioticGradients,  &abioticGradientsKeys},
        {"deussen_comparison", true,         &createDeussenComparison, &deussenComparisonKeys},
        {"deussen_circles",    false,        &createDeussenCircles,    &deussenCirclesKeys},
        {"fidelity",           false,        &createFidelity,          &fidelityKeys},
        {"ecomod",             false,        &createEcoMod,            &ecomodKeys},
    };
    return kinds;
}

const ScenarioKind* findScenarioKind(const std::string& name) {
    for (const ScenarioKind& k : scenarioKinds())
        if (name == k.name) return &k;
    return nullptr;
}

}  // namespace eco::validate
