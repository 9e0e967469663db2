// SPDX-License-Identifier: GPL-3.0-or-later
// ftm-mesh (run as `ftm mesh`): a tetrahedral tissue mesh from a segmented
// scan or a closed surface, written as Gmsh MSH 4.1 with each tetrahedron's
// tissue as its physical group (docs/meshes.md).
#include "mesher.h"
#include "output.h"
#include "tissues.h"

#include "ftm/labels.h"
#include "ftm/load.h"
#include "ftm/stl.h"

#include <getopt.h>

#include <chrono>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

using namespace ftm_mesher;

namespace {

const char *const usage_text =
    "usage: ftm mesh LABELS.nii[.gz] --tissue NAME=LABELS [--tissue ...] -o OUT.msh\n"
    "                [--mask IMAGE.nii[.gz] --above VALUE] [--axes scanner|stored]\n"
    "       ftm mesh SURFACE.stl [--tissue NAME] [--unit mm|m] -o OUT.msh\n"
    "   both:        [--size LENGTH|auto] [--smooth LENGTH] [--min-part LENGTH]\n"
    "                [--min-angle DEGREES] [--max-elements N] [--quiet] [--json]\n"
    "A tetrahedral mesh of the tissues, conforming where they meet, each\n"
    "tetrahedron's tissue its Gmsh physical group (1, 2, ... in the order of\n"
    "--tissue). LABELS: label values and ranges, e.g. grey=1-90,95. Lengths\n"
    "take a unit: 3mm, 0.003m. docs/meshes.md has the details.\n"
    "  --mask IMAGE --above V  only voxels where IMAGE (same grid) is above V\n"
    "  --axes               scanner (default: the sform/qform, as the scene's\n"
    "                       volume) or stored (the file's voxel axes)\n"
    "  --size               the largest elements' edge (auto: about 30000\n"
    "                       elements for the tissues' volume)\n"
    "  --smooth             boundaries smoothed over this Gaussian sigma\n"
    "                       (default 0.3 x size; 0mm: the voxel staircase)\n"
    "  --min-part           islands and holes smaller than a cube of this edge\n"
    "                       merged into what surrounds them (default size; 0mm:\n"
    "                       none)\n"
    "  --min-angle          smallest dihedral angle aimed at (default 10)\n"
    "  --max-elements       refuse before meshing when more are expected, and\n"
    "                       after when more were made (default 500000)\n"
    "  --unit               an STL's length unit (default mm)\n";

int usage_error(const std::string &why)
{
    std::fprintf(stderr, "ftm mesh: %s\n(ftm mesh --help for the options)\n", why.c_str());
    return 2;
}

// "3mm", "0.003m", "3 mm" -> metres; false if not a non-negative length
bool parse_length(const char *s, double *metres)
{
    char *end = nullptr;
    errno = 0;
    double v = std::strtod(s, &end);
    if (end == s || errno || !std::isfinite(v) || v < 0)
        return false;
    while (*end == ' ')
        end++;
    if (std::strcmp(end, "mm") == 0)
        *metres = v * 1e-3;
    else if (std::strcmp(end, "m") == 0)
        *metres = v;
    else
        return false;
    return true;
}

bool ends_with_stl(const std::string &s)
{
    if (s.size() < 4)
        return false;
    std::string e = s.substr(s.size() - 4);
    for (char &c : e)
        c = (char)std::tolower((unsigned char)c);
    return e == ".stl";
}

struct Options {
    std::string input, output, mask;
    std::vector<Tissue> tissues;
    bool have_above = false, quiet = false, json = false, stored = false;
    double above = 0, size = -1, smooth = -1, min_part = -1, min_angle = 10;
    double unit = 1e-3;
    long max_elements = 500000;
};

struct Clock {
    std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
    bool quiet = false;
    double elapsed() const
    {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
    void say(const std::string &what) const
    {
        if (!quiet)
            std::fprintf(stderr, "ftm mesh: [%6.1f s] %s\n", elapsed(), what.c_str());
    }
};

// tetrahedra a mesh of this size makes for this volume (mm, mm^3): fitted
// on the brain (docs/meshes.md), boundaries make more
double expected_elements(double volume_mm3, double size_mm)
{
    return volume_mm3 / (0.046 * size_mm * size_mm * size_mm);
}

double auto_size(double volume_mm3)
{
    return std::cbrt(volume_mm3 / (0.046 * 30000));
}

std::string thousands(size_t n)
{
    std::string s = std::to_string(n);
    for (int i = (int)s.size() - 3; i > 0; i -= 3)
        s.insert((size_t)i, ",");
    return s;
}

int parse(int argc, char **argv, Options *o)
{
    enum { O_MASK = 256, O_ABOVE, O_AXES, O_SIZE, O_SMOOTH, O_MIN_PART, O_MIN_ANGLE, O_MAX, O_UNIT,
           O_JSON };
    static const struct option longs[] = {
        {"tissue", required_argument, nullptr, 't'},
        {"output", required_argument, nullptr, 'o'},
        {"mask", required_argument, nullptr, O_MASK},
        {"above", required_argument, nullptr, O_ABOVE},
        {"axes", required_argument, nullptr, O_AXES},
        {"size", required_argument, nullptr, O_SIZE},
        {"smooth", required_argument, nullptr, O_SMOOTH},
        {"min-part", required_argument, nullptr, O_MIN_PART},
        {"min-angle", required_argument, nullptr, O_MIN_ANGLE},
        {"max-elements", required_argument, nullptr, O_MAX},
        {"unit", required_argument, nullptr, O_UNIT},
        {"quiet", no_argument, nullptr, 'q'},
        {"json", no_argument, nullptr, O_JSON},
        {"help", no_argument, nullptr, 'h'},
        {nullptr, 0, nullptr, 0},
    };
    std::vector<std::string> tissue_args;
    opterr = 0;
    optind = 1;
    int c;
    while ((c = getopt_long(argc, argv, ":t:o:qh", longs, nullptr)) != -1) {
        std::string arg = optarg ? optarg : "";
        char *end = nullptr;
        switch (c) {
        case 't': tissue_args.push_back(arg); break;
        case 'o': o->output = arg; break;
        case 'q': o->quiet = true; break;
        case 'h': std::fputs(usage_text, stdout); return 0;
        case O_JSON: o->json = true; break;
        case O_MASK: o->mask = arg; break;
        case O_ABOVE:
            o->above = std::strtod(arg.c_str(), &end);
            if (arg.empty() || *end || !std::isfinite(o->above))
                return usage_error("--above: '" + arg + "' is not a number");
            o->have_above = true;
            break;
        case O_AXES:
            if (arg != "scanner" && arg != "stored")
                return usage_error("--axes: '" + arg + "' (expected scanner or stored)");
            o->stored = arg == "stored";
            break;
        case O_SIZE:
            if (arg == "auto")
                o->size = -1;
            else if (!parse_length(arg.c_str(), &o->size) || !(o->size > 0))
                return usage_error("--size: '" + arg +
                                   "' is not a length > 0 with its unit (3mm, 0.003m) or auto");
            break;
        case O_SMOOTH:
        case O_MIN_PART: {
            double v;
            if (!parse_length(arg.c_str(), &v))
                return usage_error(std::string(c == O_SMOOTH ? "--smooth" : "--min-part") +
                                   ": '" + arg + "' is not a length >= 0 with its unit (2mm)");
            (c == O_SMOOTH ? o->smooth : o->min_part) = v;
            break;
        }
        case O_MIN_ANGLE:
            o->min_angle = std::strtod(arg.c_str(), &end);
            if (arg.empty() || *end || !(o->min_angle >= 0 && o->min_angle <= 30))
                return usage_error("--min-angle: '" + arg + "' (degrees, 0 .. 30)");
            break;
        case O_MAX:
            o->max_elements = std::strtol(arg.c_str(), &end, 10);
            if (arg.empty() || *end || o->max_elements < 1 || o->max_elements > 50000000)
                return usage_error("--max-elements: '" + arg + "' (1 .. 50000000)");
            break;
        case O_UNIT:
            if (arg != "mm" && arg != "m")
                return usage_error("--unit: '" + arg + "' (expected mm or m)");
            o->unit = arg == "mm" ? 1e-3 : 1;
            break;
        case ':':
            return usage_error(std::string("option ") + argv[optind - 1] + " needs a value");
        default:
            return usage_error(std::string("unknown option ") + argv[optind - 1]);
        }
    }
    if (optind != argc - 1)
        return usage_error(optind == argc ? "no input: a label map (.nii, .nii.gz) or a surface "
                                            "(.stl)"
                                          : "one input only (got '" + std::string(argv[optind + 1]) +
                                                "' too)");
    o->input = argv[optind];
    if (o->output.empty())
        return usage_error("no output: -o OUT.msh");
    const bool stl = ends_with_stl(o->input);
    if (!stl && tissue_args.empty())
        return usage_error("no tissue: --tissue NAME=LABELS (e.g. --tissue grey=1-90)");
    if (stl && tissue_args.size() > 1)
        return usage_error("a surface is one tissue: give --tissue once");
    if (stl && (!o->mask.empty() || o->have_above || o->stored))
        return usage_error("--mask, --above and --axes are for label maps, not surfaces");
    if (!o->mask.empty() != o->have_above)
        return usage_error("--mask and --above go together");
    if (tissue_args.size() > 254)
        return usage_error("at most 254 tissues");
    for (const auto &a : tissue_args) {
        Tissue t;
        std::string why;
        if (!parse_tissue(a, !stl, &t, &why))
            return usage_error("--tissue " + a + ": " + why);
        for (const auto &u : o->tissues)
            if (u.name == t.name)
                return usage_error("--tissue " + a + ": a second tissue named " + t.name);
        o->tissues.push_back(t);
    }
    if (stl && o->tissues.empty()) {
        Tissue t;
        t.name = "tissue";
        o->tissues.push_back(t);
    }
    return -1; // go on
}

struct Result {
    Tet_mesh mesh;            // in the meshing frame (mm)
    double size_mm = 0;
    bool size_auto = false;
    double smooth_mm = 0, min_part_mm = 0;
    size_t merged = 0, smoothed = 0;
    double agree_meshed = -1, agree_given = -1; // % of elements
    double agree_interior = -1;                  // % of those off the staircase
    size_t interior = 0;                         // elements off the staircase
};

// Of the tetrahedra, the percentage whose centroid is in a voxel of their
// own tissue.
// interior: only the elements whose centroid's voxel and its 26 neighbours
// are of one tissue (elements on a boundary's voxel staircase left out);
// *counted: how many elements the figure is of.
double agreement(const Tet_mesh &m, const Tissue_map &map, const double voxel_mm[3],
                 bool interior = false, size_t *counted = nullptr)
{
    size_t ok = 0, n = 0;
    for (size_t t = 0; t < m.tet_count(); t++) {
        double c[3] = {0, 0, 0};
        for (int i = 0; i < 4; i++)
            for (int k = 0; k < 3; k++)
                c[k] += m.xyz[3 * (size_t)m.tets[4 * t + (size_t)i] + (size_t)k] / 4;
        int idx[3];
        bool inside = true;
        for (int k = 0; k < 3; k++) {
            idx[k] = (int)std::lround(c[k] / voxel_mm[k]); // CGAL: voxel i's centre at i v
            inside = inside && idx[k] >= 0 && idx[k] < map.n[k];
        }
        if (interior) { // the 3 x 3 x 3 voxels around the centroid's all one tissue
            bool uniform = inside;
            for (int k = 0; uniform && k < 3; k++)
                uniform = idx[k] >= 1 && idx[k] + 1 < map.n[k];
            for (int dz = -1; uniform && dz <= 1; dz++)
                for (int dy = -1; uniform && dy <= 1; dy++)
                    for (int dx = -1; uniform && dx <= 1; dx++)
                        uniform = map.v[map.at(idx[0] + dx, idx[1] + dy, idx[2] + dz)] ==
                                  map.v[map.at(idx[0], idx[1], idx[2])];
            if (!uniform)
                continue;
        }
        n++;
        if (inside && map.v[map.at(idx[0], idx[1], idx[2])] == m.tissue[t])
            ok++;
    }
    if (counted)
        *counted = n;
    return n ? 100.0 * (double)ok / (double)n : 0;
}

int run_image(const Options &o, const Clock &clock, Result *r, ftm_volume_info *frame)
{
    ftm_label_map_def def = ftm_default_label_map_def();
    def.axes = o.stored ? FTM_VOLUME_AXES_STORED : FTM_VOLUME_AXES_SCANNER;
    ftm_label_map *labels = nullptr, *mask = nullptr;
    ftm_error err{};
    if (ftm_label_map_load(o.input.c_str(), &def, &labels, &err) != FTM_OK) {
        std::fprintf(stderr, "ftm mesh: %s\n", err.message);
        return 2;
    }
    const ftm_volume_info in = ftm_label_map_get_info(labels);
    char line[600];
    std::snprintf(line, sizeof line, "read %s: %d x %d x %d voxels of %g x %g x %g mm",
                  o.input.c_str(), in.nx, in.ny, in.nz, in.spacing.x * 1e3, in.spacing.y * 1e3,
                  in.spacing.z * 1e3);
    clock.say(line);
    if (!o.mask.empty()) {
        def.threshold = true;
        def.above = o.above;
        if (ftm_label_map_load(o.mask.c_str(), &def, &mask, &err) != FTM_OK) {
            std::fprintf(stderr, "ftm mesh: %s\n", err.message);
            ftm_label_map_destroy(labels);
            return 2;
        }
        const ftm_volume_info mi = ftm_label_map_get_info(mask);
        const double tol = 1e-6 * std::max(in.spacing.x, std::max(in.spacing.y, in.spacing.z));
        if (mi.nx != in.nx || mi.ny != in.ny || mi.nz != in.nz ||
            std::fabs(mi.spacing.x - in.spacing.x) > tol ||
            std::fabs(mi.spacing.y - in.spacing.y) > tol ||
            std::fabs(mi.spacing.z - in.spacing.z) > tol ||
            std::fabs(mi.origin.x - in.origin.x) > tol ||
            std::fabs(mi.origin.y - in.origin.y) > tol || std::fabs(mi.origin.z - in.origin.z) > tol) {
            std::fprintf(stderr,
                         "ftm mesh: %s is on another grid than %s: %d x %d x %d voxels of %g x %g "
                         "x %g mm from (%g, %g, %g) mm, against %d x %d x %d of %g x %g x %g mm "
                         "from (%g, %g, %g) mm\n",
                         o.mask.c_str(), o.input.c_str(), mi.nx, mi.ny, mi.nz, mi.spacing.x * 1e3,
                         mi.spacing.y * 1e3, mi.spacing.z * 1e3, mi.origin.x * 1e3,
                         mi.origin.y * 1e3, mi.origin.z * 1e3, in.nx, in.ny, in.nz,
                         in.spacing.x * 1e3, in.spacing.y * 1e3, in.spacing.z * 1e3,
                         in.origin.x * 1e3, in.origin.y * 1e3, in.origin.z * 1e3);
            ftm_label_map_destroy(labels);
            ftm_label_map_destroy(mask);
            return 2;
        }
        std::snprintf(line, sizeof line, "read the mask %s (above %g)", o.mask.c_str(), o.above);
        clock.say(line);
    }
    Tissue_map map;
    std::string why;
    bool ok = group_tissues(labels, mask, o.tissues, o.input, &map, &why);
    ftm_label_map_destroy(labels);
    ftm_label_map_destroy(mask);
    if (!ok) {
        std::fprintf(stderr, "ftm mesh: %s\n", why.c_str());
        return 2;
    }
    const int ntis = (int)o.tissues.size();
    const double voxel_mm[3] = {map.info.spacing.x * 1e3, map.info.spacing.y * 1e3,
                                map.info.spacing.z * 1e3};
    const double voxel_volume = voxel_mm[0] * voxel_mm[1] * voxel_mm[2];
    size_t tissue_voxels = 0;
    for (uint8_t t : map.v)
        tissue_voxels += t != 0;
    const double volume = (double)tissue_voxels * voxel_volume;
    r->size_auto = o.size < 0;
    r->size_mm = r->size_auto ? auto_size(volume) : o.size * 1e3;
    r->smooth_mm = o.smooth < 0 ? 0.3 * r->size_mm : o.smooth * 1e3;
    r->min_part_mm = o.min_part < 0 ? r->size_mm : o.min_part * 1e3;
    const double expected = expected_elements(volume, r->size_mm);
    if (expected > (double)o.max_elements) {
        std::fprintf(stderr,
                     "ftm mesh: %s: about %s tetrahedra expected at size %g mm for %.4g mm^3 of "
                     "tissue, more than --max-elements %ld: choose a larger --size (about %.3g mm "
                     "makes %ld)\n",
                     o.input.c_str(), thousands((size_t)expected).c_str(), r->size_mm, volume,
                     o.max_elements,
                     std::cbrt(volume / (0.046 * (double)o.max_elements)), o.max_elements);
        return 2;
    }
    // only the tissues' box (and room for the smoothing) is worked on
    const double sigma_vox =
        r->smooth_mm / std::min(voxel_mm[0], std::min(voxel_mm[1], voxel_mm[2]));
    crop(map, (int)std::ceil(3 * sigma_vox) + 2);
    Tissue_map given = map;
    if (r->min_part_mm > 0) {
        size_t min_voxels = (size_t)std::ceil(std::pow(r->min_part_mm, 3) / voxel_volume);
        r->merged = merge_small_parts(map, min_voxels);
    }
    std::vector<uint8_t> weights;
    if (r->smooth_mm > 0) {
        r->smoothed = smooth(map, r->smooth_mm, ntis, &weights);
        // smoothing can leave new small parts: once more
        if (r->min_part_mm > 0)
            r->merged += merge_small_parts(
                map, (size_t)std::ceil(std::pow(r->min_part_mm, 3) / voxel_volume));
    }
    std::snprintf(line, sizeof line,
                  "tissues grouped and cleaned: %zu voxels in small parts merged, %zu voxels "
                  "moved by smoothing (sigma %.2g mm); size %.3g mm%s, about %s tetrahedra",
                  r->merged, r->smoothed, r->smooth_mm, r->size_mm, r->size_auto ? " (auto)" : "",
                  thousands((size_t)expected).c_str());
    clock.say(line);
    Criteria criteria;
    criteria.size = r->size_mm;
    criteria.facet_distance = r->size_mm / 6;
    criteria.min_angle = o.min_angle;
    r->mesh = mesh_image(map.v, map.n, voxel_mm, r->smooth_mm > 0 ? &weights : nullptr, criteria,
                         [&](const std::string &s) { clock.say(s); });
    size_t slivers = remove_surface_slivers(r->mesh, o.min_angle);
    if (slivers) {
        std::snprintf(line, sizeof line, "%zu slivers on the outer surface removed", slivers);
        clock.say(line);
    }
    r->agree_meshed = agreement(r->mesh, map, voxel_mm);
    r->agree_given = agreement(r->mesh, given, voxel_mm);
    r->agree_interior = agreement(r->mesh, given, voxel_mm, true, &r->interior);
    // the meshing frame (mm, voxel 0's centre at 0) in metres, for the world
    *frame = map.info;
    frame->origin.x += 0.5 * map.info.spacing.x;
    frame->origin.y += 0.5 * map.info.spacing.y;
    frame->origin.z += 0.5 * map.info.spacing.z;
    return -1;
}

int run_surface(const Options &o, const Clock &clock, Result *r, ftm_volume_info *frame)
{
    ftm_surface *s = nullptr;
    ftm_error err{};
    if (ftm_surface_load(o.input.c_str(), true, &s, &err) != FTM_OK) {
        std::fprintf(stderr, "ftm mesh: %s\n", err.message);
        return 2;
    }
    std::vector<double> xyz(s->positions, s->positions + 3 * (size_t)s->vertex_count);
    std::vector<int32_t> tri(s->triangles, s->triangles + 3 * (size_t)s->triangle_count);
    ftm_surface_destroy(s);
    const double to_mm = o.unit * 1e3; // mesh in mm, as images
    double volume = 0;                 // enclosed, mm^3
    for (double &x : xyz)
        x *= to_mm;
    for (size_t t = 0; t < tri.size() / 3; t++) {
        const double *a = &xyz[3 * (size_t)tri[3 * t]], *b = &xyz[3 * (size_t)tri[3 * t + 1]],
                     *c = &xyz[3 * (size_t)tri[3 * t + 2]];
        volume += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                   a[2] * (b[0] * c[1] - b[1] * c[0])) /
                  6;
    }
    char line[300];
    std::snprintf(line, sizeof line, "read %s: %zu vertices, %zu facets, closed, %.4g mm^3",
                  o.input.c_str(), xyz.size() / 3, tri.size() / 3, volume);
    clock.say(line);
    r->size_auto = o.size < 0;
    r->size_mm = r->size_auto ? auto_size(volume) : o.size * 1e3;
    const double expected = expected_elements(volume, r->size_mm);
    if (expected > (double)o.max_elements) {
        std::fprintf(stderr,
                     "ftm mesh: %s: about %s tetrahedra expected at size %g mm for %.4g mm^3, "
                     "more than --max-elements %ld: choose a larger --size\n",
                     o.input.c_str(), thousands((size_t)expected).c_str(), r->size_mm, volume,
                     o.max_elements);
        return 2;
    }
    Criteria criteria;
    criteria.size = r->size_mm;
    criteria.facet_distance = r->size_mm / 6;
    criteria.min_angle = o.min_angle;
    r->mesh = mesh_surface(xyz, tri, criteria, [&](const std::string &m) { clock.say(m); },
                           o.input);
    size_t slivers = remove_surface_slivers(r->mesh, o.min_angle);
    if (slivers) {
        std::snprintf(line, sizeof line, "%zu slivers on the surface removed", slivers);
        clock.say(line);
    }
    *frame = ftm_volume_info{}; /* the file's own frame: only mm back to metres */
    return -1;
}

} // namespace

int main(int argc, char **argv)
{
    Options o;
    int rc = parse(argc, argv, &o);
    if (rc >= 0)
        return rc;
    Clock clock;
    clock.quiet = o.quiet;
    Result r;
    ftm_volume_info frame{};
    try {
        rc = ends_with_stl(o.input) ? run_surface(o, clock, &r, &frame)
                                    : run_image(o, clock, &r, &frame);
    } catch (const std::exception &e) {
        std::fprintf(stderr, "ftm mesh: %s: meshing failed: %s\n", o.input.c_str(), e.what());
        return 1;
    }
    if (rc >= 0)
        return rc;
    const int ntis = (int)o.tissues.size();
    Tet_mesh &m = r.mesh;
    const Quality q = quality(m, ntis, o.min_angle);
    for (int t = 1; t <= ntis; t++)
        if (q.per_tissue[(size_t)t] == 0) {
            std::fprintf(stderr,
                         "ftm mesh: %s: tissue %s got no elements at size %g mm (it is thinner "
                         "than the mesh there, or was merged away as a small part): choose a "
                         "smaller --size\n",
                         o.input.c_str(), o.tissues[(size_t)t - 1].name.c_str(), r.size_mm);
            return 2;
        }
    if (m.tet_count() > (size_t)o.max_elements) {
        std::fprintf(stderr,
                     "ftm mesh: %s: %s tetrahedra made, more than --max-elements %ld: nothing "
                     "written; choose a larger --size\n",
                     o.input.c_str(), thousands(m.tet_count()).c_str(), o.max_elements);
        return 2;
    }
    // into the scan's frame, in metres (the scene's and the volume's)
    Tet_mesh world = m;
    for (size_t i = 0; i < world.xyz.size() / 3; i++) {
        world.xyz[3 * i] = frame.origin.x + m.xyz[3 * i] * 1e-3;
        world.xyz[3 * i + 1] = frame.origin.y + m.xyz[3 * i + 1] * 1e-3;
        world.xyz[3 * i + 2] = frame.origin.z + m.xyz[3 * i + 2] * 1e-3;
    }
    std::vector<std::string> names;
    for (const auto &t : o.tissues)
        names.push_back(t.name);
    std::string why;
    if (!write_gmsh(o.output, world, names, &why)) {
        std::fprintf(stderr, "ftm mesh: %s\n", why.c_str());
        return 1;
    }
    const double seconds = clock.elapsed();
    std::string per;
    for (int t = 1; t <= ntis; t++)
        per += (t > 1 ? ", " : "") + o.tissues[(size_t)t - 1].name + " " +
               thousands(q.per_tissue[(size_t)t]);
    if (o.json) {
        std::printf("{\"output\": \"%s\", \"tetrahedra\": %zu, \"nodes\": %zu, \"tissues\": {",
                    o.output.c_str(), m.tet_count(), m.xyz.size() / 3);
        for (int t = 1; t <= ntis; t++)
            std::printf("%s\"%s\": %zu", t > 1 ? ", " : "", o.tissues[(size_t)t - 1].name.c_str(),
                        q.per_tissue[(size_t)t]);
        std::printf("}, \"size_mm\": %.6g, \"mean_edge_mm\": %.6g, \"min_dihedral_deg\": %.6g, "
                    "\"below_min_angle\": %zu, \"volume_mm3\": %.8g",
                    r.size_mm, q.mean_edge, q.min_angle, q.below, q.volume);
        if (r.agree_meshed >= 0)
            std::printf(", \"centroid_in_tissue_pct\": %.4f, \"centroid_in_given_map_pct\": %.4f"
                        ", \"off_staircase_elements\": %zu, \"off_staircase_in_given_map_pct\": %.4f",
                        r.agree_meshed, r.agree_given, r.interior, r.agree_interior);
        std::printf(", \"seconds\": %.3f}\n", seconds);
    } else {
        std::printf("ftm mesh: %s: %s tetrahedra (%s), %s nodes\n", o.output.c_str(),
                    thousands(m.tet_count()).c_str(), per.c_str(),
                    thousands(m.xyz.size() / 3).c_str());
        std::printf("  size %.3g mm%s, mean edge %.3g mm\n", r.size_mm,
                    r.size_auto ? " (auto)" : "", q.mean_edge);
        std::printf("  smallest dihedral angle %.2f degrees, %zu elements below %g\n", q.min_angle,
                    q.below, o.min_angle);
        if (r.agree_meshed >= 0)
            std::printf("  centroid in its own tissue: %.2f %% of the elements in the map as "
                        "meshed, %.2f %% in the map as given;\n"
                        "  off the voxel staircase (%s elements whose centroid's 27 voxels are "
                        "one tissue): %.2f %% in the map as given\n",
                        r.agree_meshed, r.agree_given, thousands(r.interior).c_str(),
                        r.agree_interior);
        std::printf("  %.1f s\n", seconds);
    }
    if (q.below > 0)
        std::fprintf(stderr,
                     "ftm mesh: warning: %zu elements have a dihedral angle below %g degrees "
                     "(the smallest %.2f)\n",
                     q.below, o.min_angle, q.min_angle);
    return 0;
}
