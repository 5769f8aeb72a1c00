/* Private to the checked edits (mesh/edit.c, flip.c, split.c): the
 * state of one thread's edits and what the three files share. The rest of
 * the library edits a mesh through mesh/mesh.h. */
#ifndef TESSEL_MESH_EDIT_H
#define TESSEL_MESH_EDIT_H

#include "mesh/mesh.h"

#define NONE TESSEL_NONE

/* One split: the edge x -> y (half-edge h = slot i of T1 = (x, y, a)) and
 * its twin (slot j of T2 = (y, x, b), or none) become x - m - y; T1 turns
 * into (x, m, a) and T3 = (m, y, a) is new, T2 into (y, m, b) and T4 =
 * (m, x, b). What it replaced is kept to take it back. */
typedef struct split_info {
    uint32_t x, y, a, b, m, T1, T2, T3, T4, i, j;
    uint32_t news[4];
    int count;         /* 2 without T2, else 4 */
    double olds[4][3]; /* unit normals of the triangles each new one replaces */
    uint32_t tri[6], twin[6];
    float box[12];
} split_info;

/* What one thread checks and flips with. Serially (splits, and the flips
 * of the serial tail) the checks query the mesh's grid, and a flip updates
 * the grid and the edge map at once. In a parallel phase of the flips (see
 * tsl_edit_flips) those two are only read: the triangles a flip changes go
 * into the thread's overlay grid, which the later checks of its block
 * query too, and the flip into a log that is applied after the phase. */
typedef struct tsl_edit_worker {
    tsl_trigrid_hits hits;
    bool parallel;
    tsl_trigrid overlay;
    uint32_t *log; /* per flip: T1, T2, u, v, a, b */
    size_t nlog, cap_log;
    uint32_t *seg; /* per block done: its key and the end of its part of log */
    size_t nseg, cap_seg;
    uint32_t *next; /* half-edges to look at in the next pass */
    size_t nnext, cap_next;
    uint32_t *tail; /* pairs that left their block, for the pass's tail */
    size_t ntail, cap_tail;
    size_t flips, invalid;
    tessel_status status;
    /* The parallel splits (tsl_edit_splits): ids below id_end are triangles
     * (0: below r->nt); the block's splits, to take back at its end; the
     * edges they moved, which the mesh's edge map does not know yet; the
     * tsl_edit_worker's own vertex and triangle ids for them. */
    size_t id_end;
    split_info *undo;
    size_t nundo, cap_undo;
    tsl_edge_map moved;
    uint32_t *moved_ab; /* the moved edges' ends, to clear the map */
    size_t nmoved, cap_moved;
    uint32_t base_v, base_t;
    size_t skinny;
} tsl_edit_worker;

/* Twins are stored and, where a parallel phase of the flips may read a
 * pair that another thread owns (tsl_edit_pair_key), loaded with relaxed atomics
 * (plain moves): such a read only finds the pair is not the reader's. */
static inline void set_twin(tsl_edit *r, uint32_t h, uint32_t g)
{
    __atomic_store_n(&r->twin[h], g, __ATOMIC_RELAXED);
    if (g != NONE)
        __atomic_store_n(&r->twin[g], h, __ATOMIC_RELAXED);
}

static inline uint32_t twin_load(const tsl_edit *r, uint32_t h)
{
    return __atomic_load_n(&r->twin[h], __ATOMIC_RELAXED);
}

static inline uint32_t he_next(uint32_t h)
{
    return h - h % 3 + (h % 3 + 1) % 3;
}
static inline uint32_t he_prev(uint32_t h)
{
    return h - h % 3 + (h % 3 + 2) % 3;
}

/* Triangle t's recorded box. In a parallel phase of the flips a check may
 * find, through a listing left from an earlier place, a triangle that
 * another thread is flipping far away; either box it reads is far, so the
 * box test rejects it, and the relaxed atomic accesses (plain moves)
 * make that read well defined. */
static inline void box_load(const tsl_edit *r, uint32_t t, float out[6])
{
    const float *b = r->box + 6 * (size_t)t;
    for (int c = 0; c < 6; c++)
        __atomic_load(&b[c], &out[c], __ATOMIC_RELAXED);
}

/* Restores triangle t's recorded box (as box_load reads it). */
static inline void box_store(tsl_edit *r, uint32_t t, const float in[6])
{
    float *b = r->box + 6 * (size_t)t;
    for (int c = 0; c < 6; c++) {
        float v = in[c];
        __atomic_store(&b[c], &v, __ATOMIC_RELAXED);
    }
}

/* The flips run in passes. A pass looks at the edges marked for it: at
 * first every edge; then the six of the two triangles of every flip (on
 * both sides) and those refused for a reason outside their own two
 * triangles (every other edge would be refused again for the same reason;
 * on 10^6 points the later passes flip a few hundred edges out of
 * 900,000).
 *
 * A pass runs in parallel, deterministically. Space is cut into blocks of
 * BLOCK_CELLS grid cells a side, coloured by the parity of their three
 * coordinates. Each pair of triangles whose boxes both fit in LONG_CELLS
 * cells goes to the block of its box's centre; the eight colours take
 * turns, and the blocks of one colour are flipped in parallel, each in
 * half-edge order by one thread. Two blocks of a colour are at least a
 * block apart, so the boxes of their pairs are more than BLOCK_CELLS - 2
 * LONG_CELLS cells apart: neither flip reads a triangle, a twin or a grid
 * cell the other writes, and none can meet the other's new triangles.
 * Pairs with a longer triangle, and pairs whose block changed because a
 * neighbour flipped first, are done after the colours, serially, in
 * half-edge order (the tail). The result depends on the mesh only, not on
 * the thread count. */
#define BLOCK_CELLS 8
#define LONG_CELLS 2
/* Blocks at most (larger blocks beyond): a pass's counting sort has 8
 * counters per block, cleared every pass. */
#define MAX_BLOCKS (1u << 18)

typedef struct blocks {
    double origin[3], size, reach;
    int n[3];
    uint32_t count; /* blocks; keys run over 8 count (colour-major) */
} blocks;

typedef struct seg_ref {
    uint32_t key, tsl_edit_worker;
    size_t index;
} seg_ref;

/* ---- mesh/edit.c ---- */

/* Cross product of triangle t's edges (twice its area along its normal). */
void tsl_edit_tri_cross(const tsl_edit *r, uint32_t t, double n[3]);
/* Lists triangle t in the grid at the box recorded for it. */
tessel_status tsl_edit_grid_list(tsl_edit *r, uint32_t t);
/* Records triangle t's new box and lists it in the grid there (in a
 * parallel phase: in the worker's overlay), unless the cells it is listed
 * in for its previous box hold the new one. fresh: t is new. *listed:
 * whether it was listed now. */
tessel_status tsl_edit_grid_add(tsl_edit *r, tsl_edit_worker *w, uint32_t t, bool fresh,
                                bool *listed);
/* *ok: the count triangles news[] of one edit (already written into the
 * mesh) each keep to their predecessor's unit normal old_n[q], are not
 * degenerate, and meet neither each other nor any other triangle beyond
 * shared vertices and edges (exact). */
tessel_status tsl_edit_check_news(const tsl_edit *r, tsl_edit_worker *w, const uint32_t *news,
                                  int count, const double (*old_n)[3], bool *ok);
/* Room for more_v vertices and more_t triangles. */
tessel_status tsl_edit_reserve(tsl_edit *r, size_t more_v, size_t more_t);
/* Whether the edge {a, b} exists, h being a half-edge leaving a (a's fan
 * walked; one fan). */
bool tsl_edit_edge_exists(const tsl_edit *r, uint32_t h, uint32_t b);
/* Twins without an edge map; vertices of several fans flagged in pinched,
 * or (pinched NULL) INVALID_ARG. */
tessel_status tsl_edit_twins(tsl_edit *r, int threads, uint8_t *pinched);
/* Whether the pair at half-edge h would make an edge at a vertex of
 * several fans (see tsl_edit.pinched). */
bool tsl_edit_pair_pinched(const tsl_edit *r, uint32_t h, uint32_t g);
/* Appends x to the array *a of *n (capacity *cap); false when out of
 * memory. */
bool tsl_push_u32(uint32_t **a, size_t *n, size_t *cap, uint32_t x);
void tsl_edit_worker_free(tsl_edit_worker *w);
void tsl_edit_blocks_init(const tsl_edit *r, blocks *b);
/* The key (colour count + block) of the pair at half-edge h, or NONE when
 * one of its triangles is long (the tail takes it). */
uint32_t tsl_edit_pair_key(const tsl_edit *r, const blocks *b, uint32_t h);
/* The blocks the workers did in a phase, by key; *m of them. */
seg_ref *tsl_edit_blocks_done(const tsl_edit_worker *ws, int nw, size_t *m);
/* After a phase's merge: the workers' tails into *tail, their logs
 * emptied for the next phase. */
tessel_status tsl_edit_gather_tails(tsl_edit_worker *ws, int nw, uint32_t **tail, size_t *ntail,
                                    size_t *cap_tail);

#endif /* TESSEL_MESH_EDIT_H */
