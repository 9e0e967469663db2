/* Internal: element forces evaluated a block of elements at a time, the
 * elements in vector lanes (elem_kernel.c, elem_block.inc), for the
 * neo-Hookean and co-rotational forces of sim_elem.c.
 *
 * Elements are grouped in blocks of FTM_EB consecutive elements of one type
 * (hexahedra first, then tetrahedra; a type's last block may be partial),
 * and every per-element array is stored lane-minor: value k of the element
 * in lane l of block b at [b's offset + k * FTM_EB + l]. A kernel of W
 * lanes (8 with AVX-512, 4 with AVX2 or portable) runs a block as FTM_EB / W
 * vectors; each lane does exactly the operations of the scalar reference
 * (ftm_neo_element_forces, the co-rotational element force of sim_elem.c)
 * in the same order, so every kernel gives the same bits as the reference
 * and as each other, on every machine. */
#ifndef FTM_SRC_ELEM_KERNEL_H
#define FTM_SRC_ELEM_KERNEL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define FTM_EB 8 /* elements per block */

/* quadrature data per element: per point the 3 nn rest gradients, then the
 * weight (hyperelastic.h) */
#define FTM_HEX_GP (8 * 25)
#define FTM_TET_GP 13

typedef struct ftm_elem_blocks {
    int32_t count;      /* blocks */
    int32_t hex_blocks; /* blocks 0 .. hex_blocks-1 hold hexahedra, the rest tetrahedra */
    int32_t hex_count;  /* elements 0 .. hex_count-1 are hexahedra */
    int32_t *lanes;     /* per block: elements in it (1 .. FTM_EB) */
    int32_t *node;      /* per block nn x FTM_EB node indices (a spare lane repeats lane 0) */
    double *gp;         /* neo-Hookean: per block nq (3 nn + 1) x FTM_EB, spare lanes 0 */
    double *grad;       /* co-rotational: per block the centre gradients, 3 nn x FTM_EB */
    double *fe;         /* per block the nodal forces, 3 nn x FTM_EB */
    double *det;        /* per block FTM_EB: the smallest J of each lane's points (neo) */
    int64_t *ok;        /* per block FTM_EB: all ones where J > 0 at every point (neo) */
    double mu, kappa;
} ftm_elem_blocks;

static inline bool ftm_eb_hex(const ftm_elem_blocks *eb, int32_t b) { return b < eb->hex_blocks; }
static inline int32_t ftm_eb_nodes(const ftm_elem_blocks *eb, int32_t b)
{
    return b < eb->hex_blocks ? 8 : 4;
}
/* the block of element e and its lane */
static inline int32_t ftm_eb_block(const ftm_elem_blocks *eb, int32_t e)
{
    return e < eb->hex_count ? e / FTM_EB : eb->hex_blocks + (e - eb->hex_count) / FTM_EB;
}
static inline int32_t ftm_eb_lane(const ftm_elem_blocks *eb, int32_t e)
{
    return (e < eb->hex_count ? e : e - eb->hex_count) % FTM_EB;
}
/* offsets of block b in the arrays above, in units of FTM_EB entries: a
 * per-node array (nn per element), and the quadrature data */
static inline size_t ftm_eb_node_off(const ftm_elem_blocks *eb, int32_t b)
{
    return b < eb->hex_blocks ? 8 * (size_t)b
                              : 8 * (size_t)eb->hex_blocks + 4 * (size_t)(b - eb->hex_blocks);
}
static inline size_t ftm_eb_gp_off(const ftm_elem_blocks *eb, int32_t b)
{
    return b < eb->hex_blocks
               ? FTM_HEX_GP * (size_t)b
               : FTM_HEX_GP * (size_t)eb->hex_blocks + FTM_TET_GP * (size_t)(b - eb->hex_blocks);
}

/* Evaluates the neo-Hookean forces of the blocks list[0 .. n-1] at
 * positions x (rest positions rest): fe, and det and ok per lane (a lane
 * with J <= 0 at a point gets fe = 0, ok = 0, det the smallest J up to that
 * point, as ftm_neo_element_forces). */
typedef void (*ftm_neo_blocks_fn)(ftm_elem_blocks *eb, const int32_t *list, int32_t n,
                                  const double *x, const double *rest);

typedef enum ftm_elem_kernel {
    FTM_ELEM_KERNEL_BEST,     /* the widest this CPU runs */
    FTM_ELEM_KERNEL_AVX2,     /* 4 lanes of AVX2, where the CPU has it (else portable) */
    FTM_ELEM_KERNEL_PORTABLE, /* 4 lanes, baseline instructions */
} ftm_elem_kernel;

/* The kernel asked for, or the closest this CPU runs; *lanes gets its width. */
ftm_neo_blocks_fn ftm_neo_blocks_kernel(ftm_elem_kernel which, int *lanes);

#endif
