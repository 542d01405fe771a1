/* The real-time-iteration MPC from C: one call of mpc_rti per control interval, no Python.
 *
 * mpc_rti.c / mpc_rti.h come from trajopt.mpc_rti.export_rti_c (the dynamics, their derivatives,
 * the QP and its solver's call in one function). Build, with the package's QP solver (the default;
 * export_rti_c writes riccati_qp.c beside mpc_rti.c):
 *
 *   cc -O3 -march=native mpc_rti_loop.c mpc_rti.c riccati_qp.c -I. -lm -o mpc_rti_loop
 *
 * or, for a step built with qp_solver="hpipm" (CASADI = the casadi package folder, which ships HPIPM
 * and BLASFEO; or an HPIPM/BLASFEO install built for the CPU):
 *
 *   cc -O3 -march=native mpc_rti_loop.c mpc_rti.c -I. -I$CASADI/include -L$CASADI \
 *      -lhpipm -lblasfeo -Wl,-rpath,$CASADI -lm -o mpc_rti_loop
 *
 * Usage: mpc_rti_loop INPUT OUTPUT STEPS
 *   INPUT holds x0 (2n), the guess w and the reference p as raw doubles, in that order; the program
 *   takes STEPS real-time iterations from x0 (the guess shifted each time, the reference held) and
 *   writes u, w_next, w_sol of the last one, then prints the mean wall and CPU time of a step [us].
 *   A controller replaces the file by its sensors: read x0, call mpc_rti, apply u, keep w_next.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "mpc_rti.h"

/* entries of a CasADi sparsity: {nrow, ncol, 1} when dense, else {nrow, ncol, colind[ncol + 1], row[nnz]} */
static casadi_int nnz(const casadi_int* sparsity) {
  casadi_int ncol = sparsity[1];
  return sparsity[2] == 1 ? sparsity[0] * ncol : sparsity[2 + ncol];
}

int main(int argc, char** argv) {
  if (argc != 4) {
    fprintf(stderr, "usage: %s INPUT OUTPUT STEPS\n", argv[0]);
    return 2;
  }
  mpc_rti_incref(); /* sets up the function's static data (HPIPM's problem layout) */
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  mpc_rti_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  const casadi_real** arg = malloc(sz_arg * sizeof(casadi_real*));
  casadi_real** res = malloc(sz_res * sizeof(casadi_real*));
  casadi_int* iw = malloc(sz_iw * sizeof(casadi_int));
  casadi_real* w = malloc(sz_w * sizeof(casadi_real));
  casadi_int n_x0 = nnz(mpc_rti_sparsity_in(0)), n_w = nnz(mpc_rti_sparsity_in(1));
  casadi_int n_p = nnz(mpc_rti_sparsity_in(2)), n_u = nnz(mpc_rti_sparsity_out(0));
  casadi_real* input = malloc((n_x0 + n_w + n_p) * sizeof(casadi_real));
  casadi_real* guess = malloc(n_w * sizeof(casadi_real));
  casadi_real* u = malloc(n_u * sizeof(casadi_real));
  casadi_real* w_next = malloc(n_w * sizeof(casadi_real));
  casadi_real* w_sol = malloc(n_w * sizeof(casadi_real));
  casadi_real* lam_g = malloc(nnz(mpc_rti_sparsity_out(3)) * sizeof(casadi_real));
  FILE* in = fopen(argv[1], "rb");
  if (!in || fread(input, sizeof(casadi_real), n_x0 + n_w + n_p, in) != (size_t)(n_x0 + n_w + n_p)) {
    fprintf(stderr, "%s must hold %lld doubles\n", argv[1], (long long)(n_x0 + n_w + n_p));
    return 2;
  }
  fclose(in);
  memcpy(guess, input + n_x0, n_w * sizeof(casadi_real));
  arg[0] = input;
  arg[1] = guess;
  arg[2] = input + n_x0 + n_w;
  res[0] = u;
  res[1] = w_next;
  res[2] = w_sol;
  res[3] = lam_g;
  int steps = atoi(argv[3]), mem = mpc_rti_checkout();
  struct timespec start, stop, cpu_start, cpu_stop;
  clock_gettime(CLOCK_MONOTONIC, &start);
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &cpu_start);
  for (int k = 0; k < steps; ++k) {
    if (k > 0) memcpy(guess, w_next, n_w * sizeof(casadi_real));
    if (mpc_rti(arg, res, iw, w, mem)) {
      fprintf(stderr, "mpc_rti failed at step %d\n", k);
      return 1;
    }
  }
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &cpu_stop);
  clock_gettime(CLOCK_MONOTONIC, &stop);
  mpc_rti_release(mem);
  mpc_rti_decref();
  double elapsed = (stop.tv_sec - start.tv_sec) * 1e6 + (stop.tv_nsec - start.tv_nsec) * 1e-3;
  double cpu = (cpu_stop.tv_sec - cpu_start.tv_sec) * 1e6 + (cpu_stop.tv_nsec - cpu_start.tv_nsec) * 1e-3;
  printf("%.3f %.3f\n", elapsed / steps, cpu / steps);
  FILE* out = fopen(argv[2], "wb");
  fwrite(u, sizeof(casadi_real), n_u, out);
  fwrite(w_next, sizeof(casadi_real), n_w, out);
  fwrite(w_sol, sizeof(casadi_real), n_w, out);
  fclose(out);
  return 0;
}
