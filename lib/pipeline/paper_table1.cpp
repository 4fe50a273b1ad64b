#include "pipeline/paper_table1.hpp"

namespace linebake {

const std::vector<PaperTable1Row>& paper_table1() {
  // Transcribed from the paper's tab:preprocess.
  static const std::vector<PaperTable1Row> rows{
      {"aneurysm", 2.3, 34, 0.39, 0.38, 2.04, 0.05, 0.8, 0.2, 0.6, 3.6},
      {"convection", 9.9, 151, 1.67, 1.62, 5.27, 0.04, 3.2, 0.3, 2.8, 11.1},
      {"turbulence", 17.5, 267, 3.01, 3.01, 9.38, 0.50, 7.7, 1.1, 5.1, 23.6},
      {"clouds", 39.6, 610, 4.63, 6.12, 14.5, 0.89, 13.5, 4.5, 9.5, 42.1},
  };
  return rows;
}

const PaperTable1Row* find_paper_table1(const std::string& dataset) {
  for (const PaperTable1Row& row : paper_table1())
    if (row.dataset == dataset) return &row;
  return nullptr;
}

}  // namespace linebake
