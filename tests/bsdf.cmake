# Scattering, sampling, lights, ray intersection and the camera: sampling
# routines against their pdfs (chi-square, moments), Fresnel/Snell closed forms,
# Phong energy conservation and reciprocity, octahedral directions (bsdf);
# light power, direct-light estimates against analytic irradiance, photon
# emission flux and distributions (lights); hit distances, normals,
# self-intersection at large and tiny scales, camera rays (accel).
pf_add_test(bsdf ${CMAKE_CURRENT_LIST_DIR}/test_bsdf.c LIBS pf_common LABELS unit)
pf_add_test(lights ${CMAKE_CURRENT_LIST_DIR}/test_lights.c LIBS pf_common LABELS unit)
pf_add_test(accel ${CMAKE_CURRENT_LIST_DIR}/test_accel.c LIBS pf_common LABELS unit)
