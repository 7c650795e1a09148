/* reserve.h: amortised growth of a malloc'd array, with overflow checks. */
#ifndef PF_RESERVE_H
#define PF_RESERVE_H

#include <stdint.h>
#include <stdlib.h>

#include "base/status.h"

/* Grows *arr (capacity *cap elements of elem bytes) to hold at least need
 * elements, doubling from 16. 0, or PF_ENOMEM (the array is left as it was). */
static inline int pf_reserve(void **arr, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap)
        return PF_OK;
    size_t ncap = *cap ? *cap : 16;
    while (ncap < need) {
        if (ncap > SIZE_MAX / 2)
            return PF_ENOMEM;
        ncap *= 2;
    }
    if (ncap > SIZE_MAX / elem)
        return PF_ENOMEM;
    void *p = realloc(*arr, ncap * elem);
    if (!p)
        return PF_ENOMEM;
    *arr = p;
    *cap = ncap;
    return PF_OK;
}

#endif
