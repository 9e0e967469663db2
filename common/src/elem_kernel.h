/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Internal: neo-Hookean and co-rotational element forces evaluated a block
 * of elements at a time, the elements in vector lanes (elem_kernel.c,
 * elem_block.inc), for sim_elem.c.
 *
 * Elements are grouped in blocks of FTM_EB consecutive elements of one type
 * (hexahedra first, then tetrahedra; a type's last block may be partial),
 * and every per-element input array is stored lane-minor: value k of the
 * element in lane l of block b at [b's offset + k * FTM_EB + l]; the forces
 * are records of FTM_EB_REC (ftm_eb_fe). A kernel of W
 * lanes (8 with AVX-512, 4 with AVX2 or portable) runs a block as FTM_EB / W
 * vectors, each lane doing one element's operations in one fixed order, so
 * every kernel gives the same bits on every machine: for neo-Hookean forces
 * exactly those of the scalar ftm_neo_element_forces; for co-rotational
 * forces those of the formulation described in elem_block.inc. */
#ifndef FTM_SRC_ELEM_KERNEL_H
#define FTM_SRC_ELEM_KERNEL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define FTM_EB 8 /* elements per block */

/* Per element data (gp) of the kinds:
 * neo-Hookean: per quadrature point the 3 nn rest gradients, then the
 *   weight (hyperelastic.h): 8 x 25 on a hexahedron, 13 on a tetrahedron;
 * co-rotational: a hexahedron's inverse Jacobians at its 8 Gauss points and
 *   then its centre (9 each, ftm_hex8_inverse_jacobians) and the 8 points'
 *   weights; a tetrahedron's 12 gradients and its volume, as neo-Hookean,
 *   except that the fourth node's gradient, which the co-rotational kernel
 *   never reads, gives its place to the volume times lambda and times mu
 *   (ftm_eb_gp_off's blocks: two of FTM_EB_MAT's cache lines fewer a block,
 *   and two multiplications). */
#define FTM_NEO_HEX_GP (8 * 25)
#define FTM_COROT_HEX_GP (9 * 9 + 8)
#define FTM_TET_GP 13
#define FTM_COROT_TET_WL 9  /* w lambda */
#define FTM_COROT_TET_WM 10 /* w mu */

typedef enum ftm_elem_kind { FTM_EK_NEO, FTM_EK_COROT } ftm_elem_kind;

typedef struct ftm_elem_blocks {
    ftm_elem_kind kind;
    int32_t count;      /* blocks */
    int32_t hex_blocks; /* blocks 0 .. hex_blocks-1 hold hexahedra, the rest tetrahedra */
    int32_t hex_count;  /* elements 0 .. hex_count-1 are hexahedra */
    int32_t hex_gp;     /* gp entries per hexahedron (FTM_NEO_HEX_GP or FTM_COROT_HEX_GP) */
    int32_t *lanes;     /* per block: elements in it (1 .. FTM_EB) */
    int32_t *node;      /* per block nn x FTM_EB node indices (a spare lane repeats lane 0) */
    double *gp;         /* per block the kind's element data, spare lanes 0 */
    double *rest;       /* per block the nodes' rest positions, 3 nn x FTM_EB
                           (co-rotational hexahedra) */
    double *u;          /* scratch, per node: x - rest (FTM_EB_U each, the
                           last not used), filled by a kernel for the nodes
                           of the blocks it evaluates */
    int32_t nodes;      /* the mesh's nodes (u holds FTM_EB_U nodes + 1) */
    double *fe;         /* per block the nodal forces, nn x FTM_EB records of
                           FTM_EB_REC (x, y, z): lane l of node a at record
                           FTM_EB a + l (ftm_eb_fe) */
    double *det;        /* per block FTM_EB: neo, the smallest J of each lane's points */
    int64_t *ok;        /* per block FTM_EB: neo, all ones where J > 0 at every point;
                           co-rotational, all ones */
    /* per block FTM_EB_MAT x FTM_EB, lane-minor: each element's material,
     * its mu (shear modulus, Lame's second parameter), kappa (bulk modulus,
     * neo-Hookean) and lambda (Lame's first, co-rotational), from its
     * label's young and poisson (ftm_sim_def.label_materials); a spare lane
     * repeats lane 0 */
    double *mat;
    /* The elements in blocks by place: place p (hexahedra 0 .. hex_count-1,
     * then tetrahedra) holds element elem_of[p], and element e is at place
     * place_of[e]. Places follow space (sim_elem.c: a Morton order of the
     * centroids), so that a press's elements fill few blocks even when the
     * mesh's own order is random, as a mesher's is. Only which block and
     * lane an element sits in changes, not what it computes: every lane is
     * independent, and a node sums its elements in element order. NULL for
     * both: places are elements. */
    int32_t *elem_of, *place_of;
} ftm_elem_blocks;

/* eb->u's doubles per node: x, y, z and a fourth never read, so that eight
 * lanes' displacements are eight 256-bit loads and a transpose */
#define FTM_EB_U 4

#define FTM_EB_MAT 3
#define FTM_EB_MU 0
#define FTM_EB_KAPPA 1
#define FTM_EB_LAMBDA 2

static inline bool ftm_eb_hex(const ftm_elem_blocks *eb, int32_t b) { return b < eb->hex_blocks; }
static inline int32_t ftm_eb_nodes(const ftm_elem_blocks *eb, int32_t b)
{
    return b < eb->hex_blocks ? 8 : 4;
}
/* A force record: x, y, z, unpadded, so that a block's records of one node
 * are 3 cache lines and a sweep's records a quarter fewer lines than padded
 * (x, y, z, 0) ones (docs/speed.md, revision 5). One record per incidence. */
#define FTM_EB_REC 3
/* the first place of block b (its lane l holds ftm_eb_elem(eb, first + l)) */
static inline int32_t ftm_eb_first(const ftm_elem_blocks *eb, int32_t b)
{
    return b < eb->hex_blocks ? FTM_EB * b : eb->hex_count + FTM_EB * (b - eb->hex_blocks);
}
/* the element at place p */
static inline int32_t ftm_eb_elem(const ftm_elem_blocks *eb, int32_t p)
{
    return eb->elem_of ? eb->elem_of[p] : p;
}
/* the block of element e and its lane */
static inline int32_t ftm_eb_block(const ftm_elem_blocks *eb, int32_t e)
{
    const int32_t p = eb->place_of ? eb->place_of[e] : e;
    return p < eb->hex_count ? p / FTM_EB : eb->hex_blocks + (p - eb->hex_count) / FTM_EB;
}
static inline int32_t ftm_eb_lane(const ftm_elem_blocks *eb, int32_t e)
{
    const int32_t p = eb->place_of ? eb->place_of[e] : e;
    return (p < eb->hex_count ? p : p - eb->hex_count) % FTM_EB;
}
/* offsets of block b in the arrays above, in units of FTM_EB entries: a
 * per-node array (nn per element), and the element data */
static inline size_t ftm_eb_node_off(const ftm_elem_blocks *eb, int32_t b)
{
    return b < eb->hex_blocks ? 8 * (size_t)b
                              : 8 * (size_t)eb->hex_blocks + 4 * (size_t)(b - eb->hex_blocks);
}
/* the force record of lane l, node a of block b, in eb->fe */
static inline size_t ftm_eb_fe(const ftm_elem_blocks *eb, int32_t b, int a, int l)
{
    return FTM_EB_REC * (FTM_EB * (ftm_eb_node_off(eb, b) + (size_t)a) + (size_t)l);
}
/* zeroed force records for every block, 64-byte aligned (free() them) */
static inline double *ftm_eb_alloc_fe(const ftm_elem_blocks *eb)
{
    const size_t bytes =
        (FTM_EB_REC * FTM_EB * ftm_eb_node_off(eb, eb->count) + 8) * sizeof(double);
    const size_t size = (bytes + 63) / 64 * 64;
    double *p = aligned_alloc(64, size);
    if (p)
        memset(p, 0, size);
    return p;
}
static inline size_t ftm_eb_gp_off(const ftm_elem_blocks *eb, int32_t b)
{
    return b < eb->hex_blocks ? (size_t)eb->hex_gp * (size_t)b
                              : (size_t)eb->hex_gp * (size_t)eb->hex_blocks +
                                    FTM_TET_GP * (size_t)(b - eb->hex_blocks);
}

/* Evaluates the blocks list[0 .. n-1] at positions x (rest positions
 * rest): fe, det and ok. Neo-Hookean: a lane with J <= 0 at a point gets
 * fe = 0, ok = 0 and det the smallest J up to that point, as
 * ftm_neo_element_forces. */
typedef void (*ftm_blocks_fn)(ftm_elem_blocks *eb, const int32_t *list, int32_t n,
                              const double *x, const double *rest);

typedef enum ftm_elem_kernel {
    FTM_ELEM_KERNEL_BEST,     /* the widest this CPU runs */
    FTM_ELEM_KERNEL_AVX2,     /* 4 lanes of AVX2, where the CPU has it (else portable) */
    FTM_ELEM_KERNEL_PORTABLE, /* 4 lanes, baseline instructions */
} ftm_elem_kernel;

/* The kernel of that kind asked for, or the closest this CPU runs; *lanes
 * gets its width. */
ftm_blocks_fn ftm_blocks_kernel(ftm_elem_kind kind, ftm_elem_kernel which, int *lanes);

#endif
