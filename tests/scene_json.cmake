# The JSON scene format: parsing, values landing in pf_scene_t, file:line
# errors, and the shipped scenes loading through pf_scene_load.
pf_add_test(scene_json test_scene_json.c LIBS pf_common LABELS unit)
