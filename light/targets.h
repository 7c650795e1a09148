/* targets.h: private to light/. The cone of directions from a point that
 * holds a specular target (light.h's pf_target_t), for the caustic photons
 * of pf_lights_emit_targeted. */
#ifndef PF_TARGETS_H
#define PF_TARGETS_H

#include "light/light.h"

/* The cone from p that holds target t: unit axis, cos of the half-angle and
 * solid angle; a point inside the sphere sees the whole sphere of directions
 * (cos -1, solid 4 pi). */
void pf_target_cone(pf_vec3 p, const pf_target_t *t, pf_vec3 *axis, float *cos_max, float *solid);

#endif
