/* sceneblob.h: the scene as a self-contained blob a worker can rebuild
 * without any file: materials, meshes (positions, normals, indices, material
 * per triangle), spheres, point/spot lights, camera. Little-endian, field by
 * field; named on the wire by its content hash (pf_hash_bytes of the blob). */
#ifndef PF_SCENEBLOB_H
#define PF_SCENEBLOB_H

#include "proto/messages.h"
#include "scene/scene.h"

#define PF_SCENEBLOB_MAGIC 0x4e435346u /* "FSCN" */
/* 3: the camera gained fov_shorter, left_handed, lens_radius and
 * focal_distance (after vfov_deg); 4: materials gained eta, k and alpha
 * (the conductor's, after le); 5: material type 4, the thin dielectric,
 * which an older worker would refuse as malformed; 6: light types 2 and 3,
 * the distant and the infinite light (same record); 7: materials gained
 * thickness (the coat's) and kd_tex, meshes uv and alpha_tex, the scene its
 * textures, the settings the pixel filter (filter_box, filter_tent); 8:
 * lights gained map, and the environment maps follow them; 9: the settings
 * path_max_depth and the materials' mix, diffuse transmission, alpha,
 * normal and bump map and textured roughness fields; 10: the same records,
 * but a sphere whose material emits is a light (light/spherelight.h), which
 * an older worker would refuse or render dark; 11: the camera gained
 * has_window, window and frame_aspect (after focal_distance); 12: materials
 * gained twosided (u8 after le), emission on both sides. Older blobs are
 * refused. */
#define PF_SCENEBLOB_VERSION 13

/* Serializes a finalized scene into out (reset first). 0 or PF_ENOMEM. */
int pf_sceneblob_write(const pf_scene_t *scene, pf_buf_t *out);

/* Rebuilds a scene from a blob, validating every count against the bytes
 * left, every index against its array, every float finite, names terminated.
 * The result is finalized. NULL with err filled ("scene blob: ...") on any
 * problem. */
pf_scene_t *pf_sceneblob_read(const uint8_t *data, size_t len, pf_error_t *err);

#endif
