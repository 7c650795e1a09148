# The mesh loaders: OBJ, MTL and PLY (common/obj.c, mtl.c, ply.c), with good
# and malformed files from tests/data/loaders/ and binary PLYs made at run time.
pf_add_test(loaders ${CMAKE_CURRENT_LIST_DIR}/test_loaders.c LIBS pf_common LABELS unit)
