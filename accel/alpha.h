/* alpha.h: alpha cut-outs (pbrt-v4's shape "alpha"): Embree filter
 * functions that skip a triangle hit where the mesh's alpha texture says
 * so, for closest hits and occlusion alike. Private to accel/. */
#ifndef PF_ALPHA_H
#define PF_ALPHA_H

#include <embree3/rtcore.h>

#include "scene/scene.h"

/* Installs the filters on g, the geometry of mesh m of scene, when the
 * mesh, or a material of one of its triangles, has an alpha texture;
 * nothing otherwise. */
void pf_alpha_attach(RTCGeometry g, const pf_scene_t *scene, size_t m);

#endif
