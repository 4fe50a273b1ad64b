#pragma once
// The paper's Table 1 (Kern et al. 2020, "Data statistics and memory requirements"): segments,
// line model size, each renderable representation's size and build time for the four data sets
// on the authors' machine. Reports print it beside the figures linebake measured.

#include <string>
#include <vector>

namespace linebake {

struct PaperTable1Row {
  std::string dataset;  // lower case, as linebake's synthetic data sets are named
  double segments_millions, line_model_mb;
  // Renderable representation (GB) and build time (s): rasterisation (tube mesh), OSP (Embree),
  // RTX (BLAS/TLAS), VRC (voxel grid).
  double raster_gb, osp_gb, rtx_gb, vrc_gb;
  double raster_s, osp_s, rtx_s, vrc_s;
};

const std::vector<PaperTable1Row>& paper_table1();
const PaperTable1Row* find_paper_table1(const std::string& dataset);

}  // namespace linebake
