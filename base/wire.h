/* wire.h: a bounds-checked cursor for reading and a growable buffer for
 * writing little-endian fields, for every byte format of the project (wire
 * messages, the scene and photon-map blobs). Every read checks the remaining length first
 * and latches an error; callers check pf_rd_ok() once at the end. */
#ifndef PF_WIRE_H
#define PF_WIRE_H

#include <stddef.h>
#include <stdint.h>


/* A growable output buffer for encoders (the cursor's writers below). */
typedef struct pf_buf {
    uint8_t *data;
    size_t len, cap;
} pf_buf_t;
void pf_buf_free(pf_buf_t *b);

/* The longest string a cursor reads or writes: a u16 length, capped. */
#define PF_WIRE_MAX_STRING 1024

typedef struct pf_rd {
    const uint8_t *p;
    size_t left;
    int err; /* latched: once set, every read returns 0 */
} pf_rd_t;

static inline pf_rd_t pf_rd_make(const void *data, size_t len) { return (pf_rd_t){ data, len, 0 }; }
uint8_t pf_rd_u8(pf_rd_t *r);
uint16_t pf_rd_u16(pf_rd_t *r);
uint32_t pf_rd_u32(pf_rd_t *r);
uint64_t pf_rd_u64(pf_rd_t *r);
/* A float; non-finite values latch an error. */
float pf_rd_f32(pf_rd_t *r);
/* Points at the next n bytes (NULL and error if fewer remain). */
const uint8_t *pf_rd_bytes(pf_rd_t *r, size_t n);
/* A u16-length string into dst (NUL-terminated; "" on error). Longer than
 * PF_WIRE_MAX_STRING, too long for dst, or holding a NUL byte: error. */
void pf_rd_str(pf_rd_t *r, char *dst, size_t cap);
static inline int pf_rd_ok(const pf_rd_t *r) { return !r->err; }
/* Fails the cursor (e.g. on an out-of-range value). */
static inline void pf_rd_fail(pf_rd_t *r) { r->err = 1; }

/* Writers append to b and return 0, or PF_ENOMEM when b cannot grow (b is
 * then left as it was). There is no latch: an encoder checks each return,
 * or stops at the first failure. pf_wr_str also returns PF_EINVAL for a string
 * longer than PF_WIRE_MAX_STRING, which no reader would accept. */
int pf_wr_u8(pf_buf_t *b, uint8_t v);
int pf_wr_u16(pf_buf_t *b, uint16_t v);
int pf_wr_u32(pf_buf_t *b, uint32_t v);
int pf_wr_u64(pf_buf_t *b, uint64_t v);
int pf_wr_f32(pf_buf_t *b, float v);
int pf_wr_bytes(pf_buf_t *b, const void *data, size_t n);
int pf_wr_str(pf_buf_t *b, const char *s);
/* Makes room for n more bytes at once (a writer that knows its size spares
 * the doublings' copies); 0 or PF_ENOMEM. */
int pf_buf_reserve(pf_buf_t *b, size_t n);
/* Appends n bytes for the caller to fill (a bulk encoder's records, packed
 * by hand) and returns where they start; NULL when b cannot grow (b is
 * then left as it was). */
uint8_t *pf_wr_space(pf_buf_t *b, size_t n);

#endif
