# Image I/O (PFM, PNG), error metrics and the `photonfarm compare` subcommand.
# compare.c is compiled into the test directly; the coordinator library is
# not needed for it.
pf_add_test(image
  ${CMAKE_SOURCE_DIR}/tests/test_image.c
  ${CMAKE_SOURCE_DIR}/coordinator/compare.c
  LIBS pf_common
  LABELS unit)
