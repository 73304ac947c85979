// The interactive part of out_dir/report.html of `eco run` (docs/report.md): plants per
// species over the simulated years, g(r) of every region (database against the synthesized
// scene) and a pan-and-zoom top view of the synthesized scene (or, without a synthesis, of
// the simulated plot), read from the files the run wrote.
#pragma once

#include "html_report.h"
#include "run.h"

namespace eco::pipeline {

/// Add the plots and the scene view of a finished run to `doc`. A view whose files cannot
/// be read becomes a line saying why (the run itself has succeeded).
void addRunViews(html::Document& doc, const RunPlan& plan);

}  // namespace eco::pipeline
