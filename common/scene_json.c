/* scene_json.c: not written yet. */
typedef int pf_placeholder_scene_json;
