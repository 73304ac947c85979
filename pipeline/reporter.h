// How a stage talks to whoever runs it: results, informational lines and progress go through
// a Reporter, so that the same stage serves the command line (stdout, stderr and bars), the
// whole-pipeline run and tests (silence) without knowing which.
#pragma once

#include <iosfwd>
#include <memory>
#include <string>

namespace eco::sim {
class Simulation;
}

namespace eco::pipeline {

/// A progress bar of a fixed number of units.
class ProgressBar {
public:
    virtual ~ProgressBar() = default;
    /// `done` units of the total are complete.
    virtual void update(long done) = 0;
    /// The work is finished (a last line with the elapsed time).
    virtual void finish() = 0;
};

/// Year-by-year progress of an undergrowth simulation.
class SimulationProgress {
public:
    virtual ~SimulationProgress() = default;
    /// After every simulated year.
    virtual void update(const sim::Simulation& simulation) = 0;
    /// The run ended (normally or by an exception).
    virtual void finish() = 0;
};

class Reporter {
public:
    virtual ~Reporter() = default;
    /// Results: the tables and "wrote ..." lines of a stage (stdout on the command line).
    virtual std::ostream& out() = 0;
    /// One informational line, without its newline (stderr on the command line).
    virtual void info(const std::string& line) = 0;
    /// A line of extra detail (phase timings and the like): shown only when asked for
    /// (eco --verbose); dropped by default.
    virtual void detail(const std::string& line) {}
    /// A progress bar labelled `label` over `total` units.
    virtual std::unique_ptr<ProgressBar> progress(const std::string& label, long total) = 0;
    /// Progress of a simulation of `totalYears` years; nullptr: none.
    virtual std::unique_ptr<SimulationProgress> simulationProgress(int totalYears) { return nullptr; }
    /// Polled by long stages (the simulation, after every year): true asks them to stop.
    virtual bool stopRequested() { return false; }
};

/// A Reporter that drops everything (library use, tests).
class SilentReporter : public Reporter {
public:
    SilentReporter();
    ~SilentReporter() override;
    std::ostream& out() override;
    void info(const std::string&) override {}
    std::unique_ptr<ProgressBar> progress(const std::string&, long) override;

private:
    std::unique_ptr<std::ostream> sink_;
};

/// Progress of computeAbiotics ("slope", "sun", ... each from 0 to 1): one bar per stage,
/// labelled "abiotics <stage>".
class AbioticsProgress {
public:
    explicit AbioticsProgress(Reporter& reporter) : reporter_(reporter) {}
    void operator()(const std::string& stage, double fraction);
    /// Close the last bar.
    void finish();

private:
    Reporter& reporter_;
    std::unique_ptr<ProgressBar> bar_;
    std::string stage_;
};

}  // namespace eco::pipeline
