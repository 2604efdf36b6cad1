#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <sys/resource.h>
#include "as/as.h"
static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec * 1e3 + t.tv_nsec / 1e6; }
int main(int argc, char **argv) {
  as_mesh_t *m = as_mesh_import(argv[1]); if (!m) return 1;
  as_build_args_t a; as_build_args_default(&a); a.structure = as_structure_kind_from_name(argv[2]);
  a.builder = as_builder_from_name(a.structure, argv[3]); a.thread_count = atoi(argv[4]); int n = atoi(argv[5]);
  for (int i = 0; i < n; i++) { struct rusage r0, r1; getrusage(RUSAGE_SELF, &r0); double t = now(); as_structure_t *s = as_structure_build(m, &a); t = now() - t; getrusage(RUSAGE_SELF, &r1); printf("%.1f(%ld) ", t, r1.ru_minflt - r0.ru_minflt); as_structure_release(s); }
  printf("\n"); return 0;
}
