// SPDX-License-Identifier: GPL-3.0-or-later
// The tissue map a label map becomes: label groups per tissue, the checks a
// map must pass, and the cleaning before meshing (tissues.cpp).
#ifndef FTM_MESHER_TISSUES_H
#define FTM_MESHER_TISSUES_H

#include "ftm/labels.h"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace ftm_mesher {

// --tissue NAME=LIST: LIST is labels and ranges, "1-90,95,200".
struct Tissue {
    std::string name;
    std::string list;
    std::vector<std::pair<int64_t, int64_t>> ranges; // inclusive
    bool has(int64_t label) const;
};

// Parses "NAME=LIST" (or "NAME" alone when labels is false, for a
// surface); false with *why on a malformed argument.
bool parse_tissue(const std::string &arg, bool labels, Tissue *t, std::string *why);

// Voxel -> tissue (0 outside, i + 1 for tissues[i]) on the label map's grid.
struct Tissue_map {
    int n[3] = {0, 0, 0};
    ftm_volume_info info{};  // the grid in metres (origin, spacing)
    std::vector<uint8_t> v;  // x fastest
    size_t at(int x, int y, int z) const { return (size_t)x + (size_t)n[0] * ((size_t)y + (size_t)n[1] * (size_t)z); }
};

// Groups the labels into tissues (only inside the mask, when there is one:
// voxels the mask leaves out are outside). Refused, naming the map, the
// tissue and the label or voxel: a label in two tissues, a single label
// (not a range) that no voxel has, a tissue without voxels, a tissue voxel
// on the image's border.
bool group_tissues(const ftm_label_map *labels, const ftm_label_map *mask,
                   const std::vector<Tissue> &tissues, const std::string &name, Tissue_map *out,
                   std::string *why);

// The map cut to the tissues' bounding box and `margin` voxels around it
// (within the image); the grid's origin moves with it.
void crop(Tissue_map &m, int margin);

// Connected parts (6-neighbours) of one tissue, or of the outside, smaller
// than min_voxels become the label around them that most of their
// neighbours have: islands and holes smaller than the mesh can hold.
// Returns the voxels changed.
size_t merge_small_parts(Tissue_map &m, size_t min_voxels);

// Smooths the tissues' boundaries: every voxel takes the tissue whose
// indicator, blurred with a Gaussian of sigma_mm, is largest there; weights
// (when not NULL) get that largest value, 0 .. 255 (CGAL's label weights,
// which make its surfaces follow the smooth boundary rather than the voxel
// staircase). Returns the voxels changed.
size_t smooth(Tissue_map &m, double sigma_mm, int tissue_count, std::vector<uint8_t> *weights);

} // namespace ftm_mesher

#endif
