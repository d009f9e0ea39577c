#pragma once
// `tirstrain report`: one self-contained HTML page with the figures a paper needs from one or several
// process results (and their validations), written whole or not at all.
#include <string>
#include <vector>

#include "report/figures.hpp"
#include "report/result_data.hpp"

namespace tirstrain::report {

struct ReportOptions {
  std::vector<std::string> results;      // process output folders (or their result.h5 files)
  std::vector<std::string> validations;  // validate output folders, one per result in order, or none
  std::string out_path;                  // the HTML file written (staged as <out_path>.partial)
  std::string title;                     // page heading; empty: "tirstrain report: " and the results' names
  ReadOptions read;                      // what the polar histograms keep
  FigureOptions figures;                 // colour-scale percentile, bins, plot width
};

struct ReportSummary {
  std::vector<std::string> figure_ids;  // the <figure> ids in page order
  std::size_t bytes = 0;                // size of the page written
};

// Reads every result, builds the figures and writes the page. Throws Error naming the input or option at
// fault; refuses an output that is an input's file or a folder.
ReportSummary write_report(const ReportOptions& options);

}  // namespace tirstrain::report
