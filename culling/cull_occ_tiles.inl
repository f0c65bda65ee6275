/*
 * cull_occ_tiles.inl — the occlusion render's tile state, included once
 * by cull_occ_raster.inl: per 8x8 tile a state (stale / clean / dirty), its
 * pixels' minimum and maximum and its effective minimum, per 64x8 strip
 * the minimum of its tiles, kept up to date lazily as spans write pixels
 * (a tile is recomputed when read after a write, or at the band's end).
 * The hidden-cluster tests during the render read them through here; the
 * query's test (cull_occ_test.inl) reads what the band's end leaves.
 */

/* One tile row's hot arrays, read once: the tile helpers below take it
 * instead of (b, ty), so a loop over a row keeps them in registers across
 * the calls that recompute a tile (which could otherwise write *b). The
 * arrays only a recompute needs are found from b and ty then. */
typedef struct trow {
    const cull_occ_buffer *b;
    size_t ty;
    uint8_t *st, *sd;                       /* tile states, strips' dirty flags */
    float *teff, *strip;
} trow;

static inline trow trow_of(const cull_occ_buffer *b, int ty)
{
    return (trow){.b = b,
                  .ty = (size_t)ty,
                  .st = b->tstate + (size_t)ty * b->tpitch,
                  .sd = b->sdirty + (size_t)ty * b->sdpitch,
                  .teff = b->teff + (size_t)ty * b->tw,
                  .strip = b->strip + (size_t)ty * b->spitch};
}

/* Tiles tx0..tx1 (a run) brought up to date from their pixels: their
 * minimum and maximum, their effective minimum (teff: the coarse value or
 * the pixels' minimum, whichever is nearer; an invalid tile's pixels are
 * all EMPTY, so its teff is its coarse value, and coarse writes raise
 * teff with the same span), their state clean. */
static inline void tiles_recompute(const trow *r, uint32_t tx0, uint32_t tx1)
{
    const cull_occ_buffer *b = r->b;
    size_t t = r->ty * b->tw;
    float *tile = b->tile + t;
    const float *tile_full = b->tile_full + t;
    b->fns.tiles(b->pool, b->tslot + t + tx0, tx1 - tx0 + 1, tile + tx0, b->tmax + t + tx0);
    for (uint32_t tx = tx0; tx <= tx1; tx++) {
        r->st[tx] = TILE_CLEAN;
        r->teff[tx] = tile_full[tx] > tile[tx] ? tile_full[tx] : tile[tx];
    }
}

/* A tile's effective minimum, recomputed first if spans wrote into it
 * since. */
static inline float band_tile(const trow *r, int tx)
{
    if (r->st[tx] == TILE_DIRTY) tiles_recompute(r, (uint32_t)tx, (uint32_t)tx);
    return r->teff[tx];
}

_Static_assert(TILE_INVALID == 0 && TILE_CLEAN == 1 && TILE_DIRTY == 2, "dirty_bytes");

/* Bit 8k + 7 set for each of the 8 tile states from st that is
 * TILE_DIRTY, exactly: a dirty byte is 0 after the xor, the others 2 or 3
 * (states are 0..2), so the zero-byte test flags exactly the dirty ones. */
static inline uint64_t dirty_bytes(const uint8_t *st)
{
    uint64_t x;
    memcpy(&x, st, sizeof x);
    x ^= 0x0101010101010101ull * TILE_DIRTY;
    return (x - 0x0101010101010101ull) & ~x & 0x8080808080808080ull;
}

/* A strip's minimum (8 tiles of one tile row), brought up to date first. */
static inline float band_strip(const trow *r, int sx)
{
    if (r->sd[sx]) {
        float m = PAD;
        if (!dirty_bytes(r->st + sx * 8)) {
            /* no dirty tile among the 8: the least of their teff as they
               are (four a vector where SSE2 is there; minps picks as
               fmin_ does, and only the order of equal values differs,
               +0 and -0, which compare the same) */
#ifdef __SSE2__
            __m128 v = _mm_min_ps(_mm_loadu_ps(r->teff + sx * 8), _mm_loadu_ps(r->teff + sx * 8 + 4));
            v = _mm_min_ps(v, _mm_movehl_ps(v, v));
            v = _mm_min_ss(v, _mm_shuffle_ps(v, v, 1));
            m = fmin_(m, _mm_cvtss_f32(v));
#else
            for (int tx = sx * 8; tx < sx * 8 + 8; tx++) m = fmin_(m, r->teff[tx]);
#endif
        } else
            for (int tx = sx * 8; tx < sx * 8 + 8; tx++) m = fmin_(m, band_tile(r, tx));
        r->strip[sx] = m;
        r->sd[sx] = 0;
    }
    return r->strip[sx];
}

/* The first tile of tx..tx1 (a run of row r) whose effective minimum is
 * not above z, or tx1 + 1. The minima are compared four a vector as they
 * stand; only a tile that fails and is dirty is brought up to date and
 * compared again. (Spans only raise pixels and coarse values only raise
 * teff, so a dirty tile's stale minimum is at most its current one: a tile
 * above z as it stands is above z brought up to date. Tiles are
 * recomputed only where the answer needs it, as band_tile does.) */
__attribute__((always_inline)) static inline int first_not_above(const trow *r, int tx, int tx1, float z)
{
    int t = tx;
#ifdef __AVX2__
    /* the AVX2 build: eight a vector (NGT_UQ: NaN fails too) */
    const __m256 v8 = _mm256_set1_ps(z);
    for (; t + 7 <= tx1; t += 8) {
        unsigned m = (unsigned)_mm256_movemask_ps(_mm256_cmp_ps(_mm256_loadu_ps(r->teff + t), v8, _CMP_NGT_UQ));
        for (; m; m &= m - 1) {
            int u = t + __builtin_ctz(m);
            if (!(band_tile(r, u) > z)) return u;
        }
    }
#endif
#ifdef __SSE2__
    const __m128 vz = _mm_set1_ps(z);
    for (; t + 3 <= tx1; t += 4) {
        /* !(teff > z): NaN fails too, as in band_tile's test */
        unsigned m = (unsigned)_mm_movemask_ps(_mm_cmpngt_ps(_mm_loadu_ps(r->teff + t), vz));
        for (; m; m &= m - 1) {
            int u = t + __builtin_ctz(m);
            if (!(band_tile(r, u) > z)) return u;
        }
    }
#endif
    for (; t <= tx1; t++)
        if (!(r->teff[t] > z) && !(band_tile(r, t) > z)) return t;
    return tx1 + 1;
}

/* Tiles tx0..tx1 of tile row ty all nearer than z? */
static bool tile_row_hidden(const cull_occ_buffer *b, int ty, int tx0, int tx1, float z)
{
    const trow r = trow_of(b, ty);
    return first_not_above(&r, tx0, tx1, z) > tx1;
}

/* Pixels [x0, x1] (may be empty) of some rows of tile row ty are about to
 * be written: their tiles made valid (an invalid one gets the band's next
 * slot, *next, its pixels EMPTY) and marked dirty, their strips marked.
 * Done once a tile row for the union of its rows' spans (a tile in the
 * union that no span reaches is only made valid: its pixels, EMPTY or as
 * they were, give the same minimum). (The flag loops cover one or two
 * entries: kept as loops, not turned into memset calls.) */
__attribute__((optimize("no-tree-loop-distribute-patterns"), always_inline)) static inline void mark_tiles(
    cull_occ_buffer *b, uint32_t *next, int ty, int x0, int x1)
{
    if (x0 > x1) return;
    uint8_t *st = b->tstate + (size_t)ty * b->tpitch;
    for (int tx = x0 >> 3; tx <= x1 >> 3; tx++) {
        if (st[tx] == TILE_INVALID) (void)occ_tile_take(b, next, tx, ty);
        st[tx] = TILE_DIRTY;
    }
    uint8_t *sd = b->sdirty + (size_t)ty * b->sdpitch;
    sd[x0 >> 6] = 1;
    sd[x1 >> 6] = 1;
    for (int sx = (x0 >> 6) + 1; sx < x1 >> 6; sx++) sd[sx] = 1;
}

/* Tile row ty's dirty tiles recomputed a run at a time, then its strips
 * and its tiles' vkeys: the end of a band. */
static void tile_row_finish(cull_occ_buffer *b, int ty)
{
    const trow r = trow_of(b, ty);
    for (uint32_t tx = 0; tx < b->tw;) {
        if (r.st[tx] != TILE_DIRTY) {
            /* to the next dirty tile 8 states a step (most tiles of a row
               are not dirty; the row's padding is TILE_CLEAN, and tpitch
               is a multiple of 64, so 8 bytes from an index below tw are
               inside the row) */
            uint64_t x = dirty_bytes(r.st + (tx & ~7u)) & ~0ull << 8 * (tx & 7u); /* from tx on */
            tx = x ? (tx & ~7u) + ((uint32_t)__builtin_ctzll(x) >> 3) : (tx & ~7u) + 8;
            continue;
        }
        uint32_t end = tx;
        while (end < b->tw && r.st[end] == TILE_DIRTY) end++;
        tiles_recompute(&r, tx, end - 1);
        tx = end;
    }
    for (uint32_t sx = 0; sx < b->t2w; sx++) (void)band_strip(&r, (int)sx);
    cull_occ_vkey_row(b, (uint32_t)ty);
}

