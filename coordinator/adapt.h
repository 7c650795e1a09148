/* adapt.h: adaptive progressive passes. From the second pass on, a pass's
 * camera samples go where the passes so far say the error is: the same
 * total as a uniform pass of spp samples (so the time plan holds), at
 * least half of spp in every pixel, the rest in proportion to an estimate
 * of each pixel's relative standard deviation (sigma / mu minimises the sum
 * of sigma^2 / (n mu^2) for a given sum of n). The counts are a function of
 * the accumulator's data alone (the passes completed), so a pass's samples
 * stay independent of what decided their number, and the image does not
 * depend on tiling, threads or workers: the coordinator computes the map
 * once per pass and hands it to every tile (accum.h weights each pixel by
 * its samples). */
#ifndef PF_ADAPT_H
#define PF_ADAPT_H

#include <stddef.h>
#include <stdint.h>

#include "coordinator/accum.h"

/* The largest count a pixel may take (the map is u16). */
#define PF_ADAPT_MAX_SPP 65535

/* The smoothing of the error estimate: a pixel's score is the maximum over
 * the (2 PF_ADAPT_MAX_R + 1)^2 pixels around it, then box-averaged over
 * (2 PF_ADAPT_BLUR_R + 1)^2, so a region that makes rare fireflies is found
 * from the few it made. */
#define PF_ADAPT_MAX_R 3
#define PF_ADAPT_BLUR_R 2

/* Hashed into a checkpoint's key (checkpoint.h) when the passes are
 * adaptive: a uniform render's checkpoint is not theirs. */
#define PF_ADAPT_KEY 0xada97u

/* A pixel takes at most this many times the image's mean score. */
#define PF_ADAPT_CAP 16.0

/* Fills counts (acc->width x acc->height, row by row) with the camera
 * samples each pixel takes in a pass of spp per pixel: their sum is width x
 * height x spp exactly (unless PF_ADAPT_MAX_SPP clips), each at least
 * (spp + 1) / 2 and at least 1, the rest shared by the score (above): the
 * spread of the passes so far around their mean where a pixel has two or
 * more, else its difference from its 8 neighbours; over its
 * neighbourhood's mean^2 + 0.01 (the compare metric's denominator). With
 * no usable estimate (no pass yet, all zero) every pixel takes spp.
 * Deterministic: the same acc gives the same counts on any machine.
 * Returns 0 or PF_ENOMEM (counts then left uniform). */
int pf_adapt_counts(const pf_accum_t *acc, int spp, uint16_t *counts);

/* For the pass's log line: " (adaptive, LO..HI per pixel)" with the
 * least and most of the n counts into buf, or "" when counts is NULL or
 * uniform. */
void pf_adapt_note(const uint16_t *counts, size_t n, char *buf, size_t len);

#endif
