/* light.c: not written yet. */
typedef int pf_placeholder_light;
