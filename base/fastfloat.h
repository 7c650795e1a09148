/* fastfloat.h: the decimal-number fast path shared by the OBJ and PLY text
 * readers, where parsing floats dominates load time. */
#ifndef PF_FASTFLOAT_H
#define PF_FASTFLOAT_H

#include <stdint.h>

/* Parses a plain decimal ("-12.5", "0.0378297") of at most 8 significant
 * digits, the form nearly every exporter writes, without strtof. m <= 2^24
 * and 10^k (k <= 10) are exact floats, so one IEEE division gives the
 * correctly rounded result, as strtof would (Clinger's fast path). Returns 0
 * for anything else (exponents, more digits, nan, inf) to fall back on strtof;
 * otherwise 1 with *out and *end (the first byte after the number) set. */
static inline int pf_fast_float(const char *p, const char **end, float *out)
{
    static const float pow10[] = { 1e0f, 1e1f, 1e2f, 1e3f, 1e4f, 1e5f, 1e6f, 1e7f, 1e8f, 1e9f, 1e10f };
    const char *s = p;
    int neg = *s == '-';
    s += neg || *s == '+';
    uint32_t m = 0;
    int exp = 0, any = 0;
    for (; *s >= '0' && *s <= '9'; s++, any = 1) {
        if (m >= 10000000u)
            return 0;
        m = m * 10 + (uint32_t)(*s - '0');
    }
    if (*s == '.') {
        for (s++; *s >= '0' && *s <= '9'; s++, any = 1, exp--) {
            if (m >= 10000000u || exp <= -10)
                return 0;
            m = m * 10 + (uint32_t)(*s - '0');
        }
    }
    if (!any || *s == 'e' || *s == 'E' || m > (1u << 24))
        return 0;
    float f = (float)m / pow10[-exp];
    *out = neg ? -f : f;
    *end = s;
    return 1;
}

#endif
