/* Order-independent checksums of per-atom data (checkpoints).
 *
 * The checksum of a table of N rows (row k belongs to atom id k, ncol values of 4 or 8 bytes each)
 * is the sum modulo 2^64 of mix(id, column, bits of the value) over every value. A sum does not
 * depend on the order in which rows are visited nor on how they are split over ranks, so each rank
 * adds up its own block and the partial sums are added (terrace_checksum_add); any single changed
 * bit changes one term, and the mixing (a 64-bit finaliser, bijective) makes the change of the sum
 * non-zero for every single-bit or single-byte change. Unsigned arithmetic, so the wrap-around
 * is defined. */
#include <stdint.h>
#include <string.h>

static uint64_t terrace_mix64(uint64_t z)
{
    z ^= z >> 30;
    z *= 0xbf58476d1ce4e5b9ULL;
    z ^= z >> 27;
    z *= 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return z;
}

/* Sum over rows first_id..first_id+count-1 of data (row-major: ncol values per row, elsize bytes
 * each, 4 or 8), as a signed 64-bit integer holding the unsigned bits. */
int64_t terrace_checksum_rows(int64_t first_id, int64_t count, int32_t ncol, int32_t elsize, const void *data)
{
    const unsigned char *p = (const unsigned char *)data;
    uint64_t sum = 0;
    for (int64_t k = 0; k < count; ++k) {
        uint64_t id = (uint64_t)(first_id + k);
        for (int32_t c = 0; c < ncol; ++c) {
            uint64_t bits = 0;
            if (elsize == 4) {
                uint32_t b;
                memcpy(&b, p, 4);
                bits = b;
            } else {
                memcpy(&bits, p, 8);
            }
            p += elsize;
            uint64_t key = terrace_mix64(id * 0x9e3779b97f4a7c15ULL + (uint64_t)c + 1);
            sum += terrace_mix64(bits ^ key) + key;
        }
    }
    int64_t out;
    memcpy(&out, &sum, 8);
    return out;
}

/* The checksum of text (names and values of the run state): the same mixing over its bytes. */
int64_t terrace_checksum_text(int64_t salt, int64_t n, const char *s)
{
    uint64_t sum = terrace_mix64((uint64_t)salt);
    for (int64_t k = 0; k < n; ++k)
        sum = terrace_mix64(sum ^ ((uint64_t)(unsigned char)s[k] + ((uint64_t)k << 8)));
    int64_t out;
    memcpy(&out, &sum, 8);
    return out;
}

/* a + b modulo 2^64 (partial sums of several ranks). */
int64_t terrace_checksum_add(int64_t a, int64_t b)
{
    uint64_t x, y;
    memcpy(&x, &a, 8);
    memcpy(&y, &b, 8);
    x += y;
    int64_t out;
    memcpy(&out, &x, 8);
    return out;
}
