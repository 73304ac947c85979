#include "reporter.h"

#include <ostream>
#include <streambuf>

namespace eco::pipeline {

namespace {
class NullBuffer : public std::streambuf {
protected:
    int overflow(int c) override { return traits_type::not_eof(c); }
    std::streamsize xsputn(const char*, std::streamsize n) override { return n; }
};
class NullBar : public ProgressBar {
public:
    void update(long) override {}
    void finish() override {}
};
NullBuffer gNullBuffer;
}  // namespace

SilentReporter::SilentReporter() : sink_(std::make_unique<std::ostream>(&gNullBuffer)) {}
SilentReporter::~SilentReporter() = default;
std::ostream& SilentReporter::out() { return *sink_; }
std::unique_ptr<ProgressBar> SilentReporter::progress(const std::string&, long) { return std::make_unique<NullBar>(); }

void AbioticsProgress::operator()(const std::string& stage, double fraction) {
    if (stage != stage_) {
        if (bar_) bar_->finish();
        bar_ = reporter_.progress("abiotics " + stage, 1000);
        stage_ = stage;
    }
    bar_->update(static_cast<long>(fraction * 1000.0 + 0.5));
}

void AbioticsProgress::finish() {
    if (bar_) bar_->finish();
    bar_.reset();
}

}  // namespace eco::pipeline
