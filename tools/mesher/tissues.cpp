// SPDX-License-Identifier: GPL-3.0-or-later
// Label maps to tissue maps: grouping, checks, cleaning (tissues.h).
#include "tissues.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <set>

namespace ftm_mesher {

bool Tissue::has(int64_t label) const
{
    for (const auto &r : ranges)
        if (label >= r.first && label <= r.second)
            return true;
    return false;
}

static bool whole_number(const std::string &s, int64_t *out)
{
    if (s.empty() || s.size() > 10)
        return false;
    for (char c : s)
        if (c < '0' || c > '9')
            return false;
    long long v = std::strtoll(s.c_str(), nullptr, 10);
    if (v > INT32_MAX)
        return false;
    *out = v;
    return true;
}

bool parse_tissue(const std::string &arg, bool labels, Tissue *t, std::string *why)
{
    size_t eq = arg.find('=');
    t->name = arg.substr(0, eq);
    if (t->name.empty() || t->name.size() > 63 ||
        t->name.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-") !=
            std::string::npos) {
        *why = "a tissue's name is 1 to 63 letters, digits, '_' or '-'";
        return false;
    }
    if (!labels) {
        if (eq != std::string::npos) {
            *why = "a surface is one tissue: give its name only (--tissue NAME)";
            return false;
        }
        return true;
    }
    if (eq == std::string::npos || eq + 1 == arg.size()) {
        *why = "expected NAME=LABELS, e.g. grey=1-90,95";
        return false;
    }
    t->list = arg.substr(eq + 1);
    size_t start = 0;
    while (start <= t->list.size()) {
        size_t comma = t->list.find(',', start);
        std::string item = t->list.substr(start, comma == std::string::npos ? std::string::npos
                                                                             : comma - start);
        size_t dash = item.find('-');
        int64_t lo, hi;
        if (dash == std::string::npos ? !whole_number(item, &lo)
                                      : !whole_number(item.substr(0, dash), &lo) ||
                                            !whole_number(item.substr(dash + 1), &hi)) {
            *why = "'" + item + "' is not a label (0 .. 2147483647) or a range of them (LOW-HIGH)";
            return false;
        }
        if (dash == std::string::npos)
            hi = lo;
        if (hi < lo) {
            *why = "the range '" + item + "' runs backwards";
            return false;
        }
        t->ranges.emplace_back(lo, hi);
        if (comma == std::string::npos)
            break;
        start = comma + 1;
    }
    return true;
}

bool group_tissues(const ftm_label_map *labels, const ftm_label_map *mask,
                   const std::vector<Tissue> &tissues, const std::string &name, Tissue_map *out,
                   std::string *why)
{
    char msg[600];
    // a label in two tissues
    for (size_t a = 0; a < tissues.size(); a++)
        for (size_t b = a + 1; b < tissues.size(); b++)
            for (const auto &r : tissues[a].ranges)
                for (const auto &q : tissues[b].ranges)
                    if (r.first <= q.second && q.first <= r.second) {
                        std::snprintf(msg, sizeof msg,
                                      "label %lld is in two tissues, %s and %s: a voxel is one "
                                      "tissue",
                                      (long long)std::max(r.first, q.first),
                                      tissues[a].name.c_str(), tissues[b].name.c_str());
                        *why = msg;
                        return false;
                    }
    const ftm_volume_info in = ftm_label_map_get_info(labels);
    out->info = in;
    out->n[0] = in.nx, out->n[1] = in.ny, out->n[2] = in.nz;
    const size_t nv = (size_t)in.nx * (size_t)in.ny * (size_t)in.nz;
    out->v.assign(nv, 0);
    const int32_t *l = ftm_label_map_data(labels);
    const int32_t *k = mask ? ftm_label_map_data(mask) : nullptr;
    std::set<int64_t> present;
    std::vector<size_t> count(tissues.size() + 1, 0);
    for (size_t i = 0; i < nv; i++) {
        if (i == 0 || l[i] != l[i - 1])
            present.insert(l[i]);
        if (k && !k[i])
            continue;
        for (size_t t = 0; t < tissues.size(); t++)
            if (tissues[t].has(l[i])) {
                out->v[i] = (uint8_t)(t + 1);
                count[t + 1]++;
                break;
            }
    }
    // what the map has, for the messages: "0, 1 .. 116"
    std::string have;
    int shown = 0;
    for (auto it = present.begin(); it != present.end() && shown < 12; shown++) {
        int64_t lo = *it, hi = lo;
        auto next = std::next(it);
        while (next != present.end() && *next == hi + 1)
            hi = *next++;
        have += (have.empty() ? "" : ", ") + std::to_string(lo) +
                (hi > lo ? " .. " + std::to_string(hi) : "");
        it = next;
        if (shown == 11 && it != present.end())
            have += ", ...";
    }
    for (size_t t = 0; t < tissues.size(); t++) {
        for (const auto &r : tissues[t].ranges)
            if (r.first == r.second && !present.count(r.first)) {
                std::snprintf(msg, sizeof msg,
                              "%s: label %lld of tissue %s is missing: no voxel has it (the map "
                              "has %s)",
                              name.c_str(), (long long)r.first, tissues[t].name.c_str(),
                              have.c_str());
                *why = msg;
                return false;
            }
        if (count[t + 1] == 0) {
            std::snprintf(msg, sizeof msg,
                          "%s: tissue %s is empty: no voxel%s has a label in %s (the map has "
                          "%s)",
                          name.c_str(), tissues[t].name.c_str(), mask ? " inside the mask" : "",
                          tissues[t].list.c_str(), have.c_str());
            *why = msg;
            return false;
        }
    }
    // a tissue on the border: its surface would be the image's edge, cut flat
    for (int z = 0; z < out->n[2]; z++)
        for (int y = 0; y < out->n[1]; y++)
            for (int x = 0; x < out->n[0]; x++) {
                bool border = x == 0 || y == 0 || z == 0 || x == out->n[0] - 1 ||
                              y == out->n[1] - 1 || z == out->n[2] - 1;
                if (!border) {
                    x = out->n[0] - 2; // jump to the last column
                    continue;
                }
                uint8_t t = out->v[out->at(x, y, z)];
                if (t) {
                    int32_t ijk[3] = {x, y, z};
                    ftm_label_map_file_voxel(labels, x, y, z, ijk);
                    std::snprintf(msg, sizeof msg,
                                  "%s: tissue %s touches the image's border at voxel (%d, %d, "
                                  "%d) (label %d, at %g %g %g mm): its surface there would be "
                                  "the image's edge; pad the image, or leave the border out of "
                                  "every tissue",
                                  name.c_str(), tissues[t - 1].name.c_str(), (int)ijk[0],
                                  (int)ijk[1], (int)ijk[2], (int)l[out->at(x, y, z)],
                                  1e3 * (in.origin.x + (x + 0.5) * in.spacing.x),
                                  1e3 * (in.origin.y + (y + 0.5) * in.spacing.y),
                                  1e3 * (in.origin.z + (z + 0.5) * in.spacing.z));
                    *why = msg;
                    return false;
                }
            }
    return true;
}

void crop(Tissue_map &m, int margin)
{
    int lo[3] = {m.n[0], m.n[1], m.n[2]}, hi[3] = {-1, -1, -1};
    for (int z = 0; z < m.n[2]; z++)
        for (int y = 0; y < m.n[1]; y++)
            for (int x = 0; x < m.n[0]; x++)
                if (m.v[m.at(x, y, z)]) {
                    const int c[3] = {x, y, z};
                    for (int a = 0; a < 3; a++) {
                        lo[a] = std::min(lo[a], c[a]);
                        hi[a] = std::max(hi[a], c[a]);
                    }
                }
    if (hi[0] < 0)
        return;
    int n[3];
    for (int a = 0; a < 3; a++) {
        lo[a] = std::max(0, lo[a] - margin);
        hi[a] = std::min(m.n[a] - 1, hi[a] + margin);
        n[a] = hi[a] - lo[a] + 1;
    }
    std::vector<uint8_t> v((size_t)n[0] * (size_t)n[1] * (size_t)n[2]);
    for (int z = 0; z < n[2]; z++)
        for (int y = 0; y < n[1]; y++)
            for (int x = 0; x < n[0]; x++)
                v[(size_t)x + (size_t)n[0] * ((size_t)y + (size_t)n[1] * (size_t)z)] =
                    m.v[m.at(x + lo[0], y + lo[1], z + lo[2])];
    m.v.swap(v);
    m.info.origin.x += lo[0] * m.info.spacing.x;
    m.info.origin.y += lo[1] * m.info.spacing.y;
    m.info.origin.z += lo[2] * m.info.spacing.z;
    for (int a = 0; a < 3; a++)
        m.n[a] = n[a];
    m.info.nx = n[0], m.info.ny = n[1], m.info.nz = n[2];
}

size_t merge_small_parts(Tissue_map &m, size_t min_voxels)
{
    const size_t nv = m.v.size();
    std::vector<int32_t> part(nv, -1);
    std::vector<size_t> queue;
    size_t changed = 0;
    int32_t parts = 0;
    const int64_t step[3] = {1, m.n[0], (int64_t)m.n[0] * m.n[1]};
    for (size_t s = 0; s < nv; s++) {
        if (part[s] >= 0)
            continue;
        const uint8_t label = m.v[s];
        queue.assign(1, s);
        part[s] = parts;
        std::vector<size_t> around(256, 0);
        for (size_t h = 0; h < queue.size(); h++) {
            const size_t i = queue[h];
            const int64_t c[3] = {(int64_t)(i % (size_t)m.n[0]),
                                  (int64_t)(i / (size_t)m.n[0] % (size_t)m.n[1]),
                                  (int64_t)(i / ((size_t)m.n[0] * (size_t)m.n[1]))};
            for (int a = 0; a < 3; a++)
                for (int d = -1; d <= 1; d += 2) {
                    int64_t q = c[a] + d;
                    if (q < 0 || q >= m.n[a])
                        continue;
                    size_t j = (size_t)((int64_t)i + d * step[a]);
                    if (m.v[j] != label)
                        around[m.v[j]]++;
                    else if (part[j] < 0) {
                        part[j] = parts;
                        queue.push_back(j);
                    }
                }
        }
        parts++;
        if (queue.size() >= min_voxels)
            continue;
        size_t best = 256;
        for (size_t t = 0; t < 256; t++)
            if (around[t] && (best == 256 || around[t] > around[best]))
                best = t;
        if (best == 256)
            continue; // the whole image is one part
        for (size_t i : queue)
            m.v[i] = (uint8_t)best;
        changed += queue.size();
    }
    return changed;
}

// A Gaussian blur along each axis in turn, within the image (the weights cut
// at the edges, which are outside anyway).
static void blur(std::vector<float> &a, const int n[3], const double sigma[3])
{
    std::vector<float> line, out;
    const size_t step[3] = {1, (size_t)n[0], (size_t)n[0] * (size_t)n[1]};
    for (int ax = 0; ax < 3; ax++) {
        if (!(sigma[ax] > 0))
            continue;
        const int r = (int)std::ceil(3 * sigma[ax]);
        std::vector<float> w(2 * (size_t)r + 1);
        float sum = 0;
        for (int i = -r; i <= r; i++)
            sum += w[(size_t)(i + r)] = (float)std::exp(-0.5 * i * i / (sigma[ax] * sigma[ax]));
        for (float &x : w)
            x /= sum;
        const int len = n[ax];
        line.resize((size_t)len);
        out.resize((size_t)len);
        const int o1 = ax == 0 ? 1 : 0, o2 = ax == 2 ? 1 : 2;
        for (int u = 0; u < n[o1]; u++)
            for (int v = 0; v < n[o2]; v++) {
                const size_t base = (size_t)u * step[o1] + (size_t)v * step[o2];
                for (int i = 0; i < len; i++)
                    line[(size_t)i] = a[base + (size_t)i * step[ax]];
                for (int i = 0; i < len; i++) {
                    float acc = 0;
                    const int k0 = std::max(-r, -i), k1 = std::min(r, len - 1 - i);
                    for (int k = k0; k <= k1; k++)
                        acc += w[(size_t)(k + r)] * line[(size_t)(i + k)];
                    out[(size_t)i] = acc;
                }
                for (int i = 0; i < len; i++)
                    a[base + (size_t)i * step[ax]] = out[(size_t)i];
            }
    }
}

size_t smooth(Tissue_map &m, double sigma_mm, int tissue_count, std::vector<uint8_t> *weights)
{
    const size_t nv = m.v.size();
    const double sigma[3] = {sigma_mm / (1000 * m.info.spacing.x),
                             sigma_mm / (1000 * m.info.spacing.y),
                             sigma_mm / (1000 * m.info.spacing.z)};
    std::vector<float> best(nv, -1.0f), ind(nv);
    std::vector<uint8_t> label(nv, 0);
    for (int t = 0; t <= tissue_count; t++) {
        for (size_t i = 0; i < nv; i++)
            ind[i] = m.v[i] == t ? 1.0f : 0.0f;
        blur(ind, m.n, sigma);
        for (size_t i = 0; i < nv; i++)
            if (ind[i] > best[i]) {
                best[i] = ind[i];
                label[i] = (uint8_t)t;
            }
    }
    size_t changed = 0;
    for (int z = 0; z < m.n[2]; z++)
        for (int y = 0; y < m.n[1]; y++)
            for (int x = 0; x < m.n[0]; x++) {
                const size_t i = m.at(x, y, z);
                // the image's border stays outside: the domain ends there
                bool border = x == 0 || y == 0 || z == 0 || x == m.n[0] - 1 ||
                              y == m.n[1] - 1 || z == m.n[2] - 1;
                uint8_t t = border ? 0 : label[i];
                changed += t != m.v[i];
                m.v[i] = t;
            }
    if (weights) {
        weights->resize(nv);
        for (size_t i = 0; i < nv; i++)
            (*weights)[i] = (uint8_t)std::lround(std::min(255.0f, 255.0f * best[i]));
    }
    return changed;
}

} // namespace ftm_mesher
