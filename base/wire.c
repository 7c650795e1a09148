/* wire.c: the byte-order layer of the protocol and the blobs. A read cursor that checks the
 * remaining length before every field and latches the first error, and a
 * growable output buffer with little-endian writers. Integers are assembled
 * by shift and mask, so the code means the same on any host; a float crosses
 * as the 4 bytes of its IEEE 754 bit pattern. Owns nothing beyond the
 * pf_buf_t storage it grows. Reentrant: any thread may use its own cursor or
 * buffer. */
#include "base/wire.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "base/status.h"

/* ---- reading ---- */

/* Claims n bytes: the pointer to them, or NULL (with the error latched) when
 * fewer remain or an earlier read already failed. */
static const uint8_t *s_take(pf_rd_t *r, size_t n)
{
    if (r->err || r->left < n) {
        r->err = 1;
        return NULL;
    }
    const uint8_t *p = r->p;
    r->p += n;
    r->left -= n;
    return p;
}

uint8_t pf_rd_u8(pf_rd_t *r)
{
    const uint8_t *p = s_take(r, 1);
    return p ? p[0] : 0;
}

uint16_t pf_rd_u16(pf_rd_t *r)
{
    const uint8_t *p = s_take(r, 2);
    return p ? (uint16_t)(p[0] | (uint16_t)p[1] << 8) : 0;
}

uint32_t pf_rd_u32(pf_rd_t *r)
{
    const uint8_t *p = s_take(r, 4);
    if (!p)
        return 0;
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

uint64_t pf_rd_u64(pf_rd_t *r)
{
    uint64_t lo = pf_rd_u32(r);
    uint64_t hi = pf_rd_u32(r);
    return r->err ? 0 : lo | hi << 32;
}

float pf_rd_f32(pf_rd_t *r)
{
    uint32_t u = pf_rd_u32(r);
    float f;
    memcpy(&f, &u, sizeof f);
    if (!isfinite(f)) {
        r->err = 1;
        return 0.0f;
    }
    return f;
}

const uint8_t *pf_rd_bytes(pf_rd_t *r, size_t n)
{
    return s_take(r, n);
}

void pf_rd_str(pf_rd_t *r, char *dst, size_t cap)
{
    if (cap > 0)
        dst[0] = '\0';
    size_t n = pf_rd_u16(r);
    if (r->err || n > PF_WIRE_MAX_STRING || n >= cap) {
        r->err = 1;
        return;
    }
    const uint8_t *p = s_take(r, n);
    if (!p || memchr(p, 0, n)) {
        r->err = 1;
        return;
    }
    memcpy(dst, p, n);
    dst[n] = '\0';
}

/* ---- writing ---- */

/* Makes room for n more bytes, doubling the capacity so that appending is
 * amortized O(1). Every size computation is checked: a request that would
 * overflow size_t fails like an allocation failure. */
static int s_reserve(pf_buf_t *b, size_t n)
{
    if (n > SIZE_MAX - b->len)
        return PF_ENOMEM;
    size_t need = b->len + n;
    if (need <= b->cap)
        return PF_OK;
    size_t cap = b->cap ? b->cap : 256;
    while (cap < need)
        cap = cap > SIZE_MAX / 2 ? need : cap * 2;
    uint8_t *p = realloc(b->data, cap);
    if (!p)
        return PF_ENOMEM;
    b->data = p;
    b->cap = cap;
    return PF_OK;
}

int pf_buf_reserve(pf_buf_t *b, size_t n)
{
    if (n > SIZE_MAX - b->len)
        return PF_ENOMEM;
    if (b->len + n <= b->cap)
        return PF_OK;
    uint8_t *p = realloc(b->data, b->len + n);
    if (!p)
        return PF_ENOMEM;
    b->data = p;
    b->cap = b->len + n;
    return PF_OK;
}

uint8_t *pf_wr_space(pf_buf_t *b, size_t n)
{
    if (s_reserve(b, n))
        return NULL;
    uint8_t *p = b->data + b->len;
    b->len += n;
    return p;
}

int pf_wr_u8(pf_buf_t *b, uint8_t v)
{
    if (s_reserve(b, 1))
        return PF_ENOMEM;
    b->data[b->len++] = v;
    return PF_OK;
}

int pf_wr_u16(pf_buf_t *b, uint16_t v)
{
    if (s_reserve(b, 2))
        return PF_ENOMEM;
    uint8_t *p = b->data + b->len;
    p[0] = (uint8_t)(v & 0xff);
    p[1] = (uint8_t)(v >> 8);
    b->len += 2;
    return PF_OK;
}

int pf_wr_u32(pf_buf_t *b, uint32_t v)
{
    if (s_reserve(b, 4))
        return PF_ENOMEM;
    uint8_t *p = b->data + b->len;
    p[0] = (uint8_t)(v & 0xff);
    p[1] = (uint8_t)(v >> 8 & 0xff);
    p[2] = (uint8_t)(v >> 16 & 0xff);
    p[3] = (uint8_t)(v >> 24);
    b->len += 4;
    return PF_OK;
}

int pf_wr_u64(pf_buf_t *b, uint64_t v)
{
    if (s_reserve(b, 8))
        return PF_ENOMEM;
    /* Reserved up front so that a failure cannot leave half a field. */
    pf_wr_u32(b, (uint32_t)(v & 0xffffffffu));
    pf_wr_u32(b, (uint32_t)(v >> 32));
    return PF_OK;
}

int pf_wr_f32(pf_buf_t *b, float v)
{
    uint32_t u;
    memcpy(&u, &v, sizeof u);
    return pf_wr_u32(b, u);
}

int pf_wr_bytes(pf_buf_t *b, const void *data, size_t n)
{
    if (n == 0)
        return PF_OK;
    if (s_reserve(b, n))
        return PF_ENOMEM;
    memcpy(b->data + b->len, data, n);
    b->len += n;
    return PF_OK;
}

int pf_wr_str(pf_buf_t *b, const char *s)
{
    size_t n = strlen(s);
    if (n > PF_WIRE_MAX_STRING)
        return PF_EINVAL;
    if (s_reserve(b, 2 + n))
        return PF_ENOMEM;
    pf_wr_u16(b, (uint16_t)n);
    pf_wr_bytes(b, s, n);
    return PF_OK;
}

void pf_buf_free(pf_buf_t *b)
{
    if (!b)
        return;
    free(b->data);
    b->data = NULL;
    b->len = b->cap = 0;
}
