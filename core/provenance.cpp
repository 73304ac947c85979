#include "provenance.h"

#include <atomic>
#include <ctime>

namespace eco {

namespace {
std::atomic<bool> gRecorded{true};
}  // namespace

void setProvenanceRecorded(bool recorded) { gRecorded = recorded; }
bool provenanceRecorded() { return gRecorded; }

void writeProvenance(h5::File& file, const std::vector<ProvenanceEntry>& entries) {
    if (!provenanceRecorded()) return;
    file.ensureGroup(kProvenanceGroup);
    file.setAttr(kProvenanceGroup, "note",
                 std::string("measured, not computed: varies between runs of the same inputs and seed; comparison "
                             "tools skip this group (eco --no-provenance omits it)"));
    for (const ProvenanceEntry& e : entries)
        std::visit([&](const auto& v) { file.setAttr(kProvenanceGroup, e.name, v); }, e.value);
}

std::optional<double> readProvenanceDouble(const h5::File& file, const std::string& name,
                                           const std::string& legacyRootAttr) {
    if (file.hasAttr(kProvenanceGroup, name)) return file.attrDouble(kProvenanceGroup, name);
    if (!legacyRootAttr.empty() && file.hasAttr("/", legacyRootAttr)) return file.attrDouble("/", legacyRootAttr);
    return std::nullopt;
}

std::optional<std::string> readProvenanceString(const h5::File& file, const std::string& name,
                                                const std::string& legacyRootAttr) {
    if (file.hasAttr(kProvenanceGroup, name)) return file.attrString(kProvenanceGroup, name);
    if (!legacyRootAttr.empty() && file.hasAttr("/", legacyRootAttr)) return file.attrString("/", legacyRootAttr);
    return std::nullopt;
}

std::string utcTimestamp() {
    const std::time_t now = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&now, &tm);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return buf;
}

}  // namespace eco
