/* The QP of one real-time iteration, solved on its stage structure: Riccati recursion, and a primal-dual
 * interior point (Mehrotra predictor-corrector) on the variable bounds when the bounds are needed.
 *
 *   min 1/2 z' diag(h) z + g' z   s.t.  x_{k+1} = A_k x_k + B_k u_k + b_k (k < N),  x_0 = lbx[0:NX],
 *                                       lbx <= z <= ubx (entries at +-inf are free),
 *   z = (x_0, u_0, x_1, u_1, ..., x_N), [A_k B_k] = jac[:, k NZ : (k + 1) NZ] (column-major).
 *
 * First the equality-constrained QP is solved (one Riccati factorisation and solve); when its solution
 * satisfies every bound it is the solution of the bounded QP too (the KKT conditions hold with zero bound
 * multipliers) and the solver returns it. Otherwise a Mehrotra predictor-corrector interior point starts
 * from it (slacks at least START_SLACK, multipliers MU0 / slack) and stops when complementarity, the
 * dynamics' and bounds' residuals and the torques' stationarity are within PSDM_QP_TOL, or at the cap
 * PSDM_QP_MAX_ITER; its iterate is then held inside the bounds (a capped step's torques stay within their
 * limits). Each Newton step is the equality-constrained QP in the increment with the barrier's diagonal
 * added to h: one Riccati factorisation per iteration, two solves (predictor, corrector).
 * lam_g are the dynamics' multipliers in CasADi's sign (Lagrangian f + lam_g' (x_{k+1} - A_k x_k - B_k u_k)),
 * from the stationarity of the states.
 *
 * Sizes and options come as macros (trajopt.riccati_qp writes them in front of this file): NX, NU, NH (the
 * horizon), PSDM_QP_MAX_ITER, PSDM_QP_TOL, PSDM_QP_NAME. The entry points follow CasADi's external-function
 * API, so casadi.external loads the compiled file and CasADi's generated code calls it.
 */
#include <math.h>
#include <string.h>

typedef double casadi_real;
typedef long long int casadi_int;

#define NZ (NX + NU)
#define NW (NZ * NH + NX)
#define NB (NX * NH)
#define PASTE(a, b) a##_##b
#define EXPAND(a, b) PASTE(a, b)
#define FN(suffix) EXPAND(PSDM_QP_NAME, suffix)
#define AB(jac, k, i, j) ((jac)[((k) * NZ + (j)) * NX + (i)])
#define STEP_TO_BOUNDARY 0.995
#define START_SLACK 1e-1
#define MU0 1.0

/* workspace layout (doubles) */
#define W_P 0                                /* P_k, k = 1..N: NX x NX each (row-major) */
#define W_L (W_P + (NH + 1) * NX * NX)       /* Cholesky factor of R_k + B_k' P B_k: NU x NU */
#define W_Y (W_L + NH * NU * NU)             /* L_k^-1 (B_k' P A_k + S_k): NU x NX */
#define W_K (W_Y + NH * NU * NX)             /* feedback -(R + B'PB)^-1 (B'PA): NU x NX */
#define W_KFF (W_K + NH * NU * NX)           /* feedforward: NU */
#define W_MT (W_KFF + NH * NU)               /* scratch ([A B]' P): NZ x NX */
#define W_G (W_MT + NZ * NX)                 /* scratch [A B]' P [A B] + diag: NZ x NZ */
#define W_VEC (W_G + NZ * NZ)                /* scratch vectors: 4 NZ */
#define W_IPM (W_VEC + 4 * NZ)               /* interior point vectors: 17 NW */
#define W_NU (W_IPM + 17 * NW)              /* the dynamics' multipliers: NB */
#define W_RD (W_NU + NB)                    /* the dynamics' residual (NB) and a zero x_0 step (NX) */
#define W_SIZE (W_RD + NB + NX)

static const casadi_int sp_w[3] = {NW, 1, 1};
static const casadi_int sp_b[3] = {NB, 1, 1};
static const casadi_int sp_jac[3] = {NX, NZ * NH, 1};

casadi_int FN(n_in)(void) { return 6; }
casadi_int FN(n_out)(void) { return 2; }
const casadi_int* FN(sparsity_in)(casadi_int i) { return i == 2 ? sp_jac : i == 3 ? sp_b : sp_w; }
const casadi_int* FN(sparsity_out)(casadi_int i) { return i == 1 ? sp_b : sp_w; }
const char* FN(name_in)(casadi_int i) {
  static const char* names[6] = {"h", "g", "jac", "b", "lbx", "ubx"};
  return i >= 0 && i < 6 ? names[i] : 0;
}
const char* FN(name_out)(casadi_int i) {
  static const char* names[2] = {"z", "lam_g"};
  return i >= 0 && i < 2 ? names[i] : 0;
}
int FN(work)(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w) {
  *sz_arg = 6;
  *sz_res = 2;
  *sz_iw = 0;
  *sz_w = W_SIZE;
  return 0;
}

/* The dot product of two NX-vectors in four interleaved partial sums (independent chains of operations). */
static inline double dot(const double* x, const double* y) {
  double s[4] = {0.0, 0.0, 0.0, 0.0};
  int i = 0;
  for (; i + 3 < NX; i += 4) {
    s[0] += x[i] * y[i];
    s[1] += x[i + 1] * y[i + 1];
    s[2] += x[i + 2] * y[i + 2];
    s[3] += x[i + 3] * y[i + 3];
  }
  for (; i < NX; ++i) s[i % 4] += x[i] * y[i];
  return (s[0] + s[1]) + (s[2] + s[3]);
}

/* Riccati factorisation of the equality-constrained QP with Hessian diag(d): P_k, L_k, Y_k, K_k. 1 when a
 * torque block is not positive definite. Rows accumulate in local arrays (kept in registers, no aliasing
 * with the workspace) and dot products in four partial sums (independent chains): with the sizes as
 * constants, 52 -> 35 us for the Panda's N = 20 QP on one core, against the plain loops. */
static int factor(const double* d, const double* jac, double* w) {
  double* mt = w + W_MT;
  double* g = w + W_G;
  double* p_next = w + W_P + NH * NX * NX;
  for (int i = 0; i < NX * NX; ++i) p_next[i] = 0.0;
  for (int i = 0; i < NX; ++i) p_next[i * NX + i] = d[NH * NZ + i];
  for (int k = NH - 1; k >= 0; --k) {
    p_next = w + W_P + (k + 1) * NX * NX;
    for (int j = 0; j < NZ; ++j) { /* mt[j] = column j of [A B], times P */
      double acc[NX];
      for (int i = 0; i < NX; ++i) acc[i] = 0.0;
      for (int l = 0; l < NX; ++l) {
        const double a = AB(jac, k, l, j);
        const double* p_row = p_next + l * NX;
        for (int i = 0; i < NX; ++i) acc[i] += a * p_row[i];
      }
      for (int i = 0; i < NX; ++i) mt[j * NX + i] = acc[i];
    }
    for (int a = 0; a < NZ; ++a) {
      const double* col = &AB(jac, k, 0, a);
      for (int b = a; b < NZ; ++b) {
        g[a * NZ + b] = g[b * NZ + a] = dot(col, mt + b * NX);
      }
      g[a * NZ + a] += d[k * NZ + a];
    }
    double* l = w + W_L + k * NU * NU;
    for (int i = 0; i < NU; ++i) { /* Cholesky of the torque block */
      for (int j = 0; j <= i; ++j) {
        double s = g[(NX + i) * NZ + NX + j];
        for (int m = 0; m < j; ++m) s -= l[i * NU + m] * l[j * NU + m];
        if (i == j) {
          if (!(s > 0.0)) return 1;
          l[i * NU + i] = sqrt(s);
        } else {
          l[i * NU + j] = s / l[j * NU + j];
        }
      }
    }
    double* y = w + W_Y + k * NU * NX;
    for (int i = 0; i < NU; ++i) { /* Y = L^-1 (B'PA) */
      double acc[NX];
      for (int c = 0; c < NX; ++c) acc[c] = g[(NX + i) * NZ + c];
      for (int m = 0; m < i; ++m) {
        const double lim = l[i * NU + m];
        for (int c = 0; c < NX; ++c) acc[c] -= lim * y[m * NX + c];
      }
      for (int c = 0; c < NX; ++c) y[i * NX + c] = acc[c] / l[i * NU + i];
    }
    double* kk = w + W_K + k * NU * NX;
    for (int i = NU - 1; i >= 0; --i) { /* K = -L'^-1 Y */
      double acc[NX];
      for (int c = 0; c < NX; ++c) acc[c] = y[i * NX + c];
      for (int m = i + 1; m < NU; ++m) {
        const double lmi = l[m * NU + i];
        for (int c = 0; c < NX; ++c) acc[c] += lmi * kk[m * NX + c];
      }
      for (int c = 0; c < NX; ++c) kk[i * NX + c] = -acc[c] / l[i * NU + i];
    }
    if (k == 0) break;
    double* p = w + W_P + k * NX * NX; /* P_k = Q + A'PA - Y'Y */
    for (int i = 0; i < NX; ++i) {
      double acc[NX];
      for (int j = 0; j < NX; ++j) acc[j] = g[i * NZ + j];
      for (int m = 0; m < NU; ++m) {
        const double ymi = y[m * NX + i];
        for (int j = 0; j < NX; ++j) acc[j] -= ymi * y[m * NX + j];
      }
      for (int j = 0; j < NX; ++j) p[i * NX + j] = acc[j];
    }
  }
  return 0;
}

/* The solution z of the factorised QP with gradient q: the vector recursion backwards, the states forwards. */
static void solve(const double* q, const double* jac, const double* b, const double* x0, double* z, double* w) {
  double* p = w + W_VEC;
  double* pb = p + NZ;
  double* gv = pb + NZ;
  double* yv = gv + NZ;
  for (int i = 0; i < NX; ++i) p[i] = q[NH * NZ + i];
  for (int k = NH - 1; k >= 0; --k) {
    const double* pn = w + W_P + (k + 1) * NX * NX;
    const double* bk = b + k * NX;
    double acc[NX]; /* P b + p, by rows of the symmetric P */
    for (int i = 0; i < NX; ++i) acc[i] = p[i];
    for (int j = 0; j < NX; ++j) {
      const double bj = bk[j];
      for (int i = 0; i < NX; ++i) acc[i] += bj * pn[j * NX + i];
    }
    for (int i = 0; i < NX; ++i) pb[i] = acc[i];
    for (int a = 0; a < NZ; ++a) gv[a] = q[k * NZ + a] + dot(&AB(jac, k, 0, a), pb);
    const double* l = w + W_L + k * NU * NU;
    for (int i = 0; i < NU; ++i) {
      double s = gv[NX + i];
      for (int m = 0; m < i; ++m) s -= l[i * NU + m] * yv[m];
      yv[i] = s / l[i * NU + i];
    }
    double* kff = w + W_KFF + k * NU;
    for (int i = NU - 1; i >= 0; --i) {
      double s = yv[i];
      for (int m = i + 1; m < NU; ++m) s -= l[m * NU + i] * (-kff[m]);
      kff[i] = -s / l[i * NU + i];
    }
    if (k == 0) break;
    const double* y = w + W_Y + k * NU * NX;
    for (int i = 0; i < NX; ++i) {
      double s = gv[i];
      for (int m = 0; m < NU; ++m) s -= y[m * NX + i] * yv[m];
      p[i] = s;
    }
  }
  for (int i = 0; i < NX; ++i) z[i] = x0[i];
  for (int k = 0; k < NH; ++k) {
    const double* x = z + k * NZ;
    double* u = z + k * NZ + NX;
    const double* kk = w + W_K + k * NU * NX;
    const double* kff = w + W_KFF + k * NU;
    for (int i = 0; i < NU; ++i) u[i] = kff[i] + dot(kk + i * NX, x);
    double acc[NX];
    for (int i = 0; i < NX; ++i) acc[i] = b[k * NX + i];
    for (int a = 0; a < NZ; ++a) {
      const double* col = &AB(jac, k, 0, a);
      const double v = x[a];
      for (int i = 0; i < NX; ++i) acc[i] += col[i] * v;
    }
    double* xn = z + (k + 1) * NZ;
    for (int i = 0; i < NX; ++i) xn[i] = acc[i];
  }
}

/* The dynamics' multipliers from the stationarity of x_1..x_N; returns the largest stationarity residual of
 * the torques (the remaining rows). r = h z + g - ll + lu is the gradient without the dynamics. */
static double multipliers(const double* r, const double* jac, double* nu) {
  for (int i = 0; i < NX; ++i) nu[(NH - 1) * NX + i] = -r[NH * NZ + i];
  for (int k = NH - 1; k >= 1; --k) {
    for (int a = 0; a < NX; ++a) nu[(k - 1) * NX + a] = dot(&AB(jac, k, 0, a), nu + k * NX) - r[k * NZ + a];
  }
  double worst = 0.0;
  for (int k = 0; k < NH; ++k) {
    for (int a = NX; a < NZ; ++a) worst = fmax(worst, fabs(r[k * NZ + a] - dot(&AB(jac, k, 0, a), nu + k * NX)));
  }
  return worst;
}

/* Largest step in (0, 1] keeping v + alpha dv >= 0 where the bound exists. */
static double max_step(const double* v, const double* dv, const double* has, double alpha) {
  for (int i = NX; i < NW; ++i) {
    if (has[i] != 0.0 && dv[i] < 0.0) alpha = fmin(alpha, -v[i] / dv[i]);
  }
  return alpha;
}

/* The Newton step dz for complementarity targets tl, tu from the iterate (z, slacks, multipliers): the
 * equality-constrained QP in dz with Hessian h + ll/sl + lu/su and the dynamics' residual rd, then the
 * slacks' and multipliers' steps. In this (increment) form the right-hand side stays of the multipliers'
 * size as the slacks of active bounds go to zero. */
static int direction(const double* const* in, double* w, int refactor) {
  double* v = w + W_IPM;
  double *z = v, *sl = v + NW, *su = v + 2 * NW, *ll = v + 3 * NW, *lu = v + 4 * NW, *tl = v + 5 * NW;
  double *tu = v + 6 * NW, *d = v + 7 * NW, *q = v + 8 * NW, *dz = v + 9 * NW, *dsl = v + 10 * NW;
  double *dsu = v + 11 * NW, *dll = v + 12 * NW, *dlu = v + 13 * NW, *hl = v + 14 * NW, *hu = v + 15 * NW;
  const double *h = in[0], *g = in[1], *lb = in[4], *ub = in[5];
  for (int i = 0; i < NW; ++i) {
    double di = h[i], qi = h[i] * z[i] + g[i];
    if (hl[i] != 0.0) {
      di += ll[i] / sl[i];
      qi += ll[i] / sl[i] * (z[i] - lb[i] - sl[i]) - tl[i] / sl[i];
    }
    if (hu[i] != 0.0) {
      di += lu[i] / su[i];
      qi += tu[i] / su[i] - lu[i] / su[i] * (ub[i] - z[i] - su[i]);
    }
    d[i] = di;
    q[i] = qi;
  }
  if (refactor && factor(d, in[2], w)) return 1;
  solve(q, in[2], w + W_RD, w + W_RD + NB, dz, w);
  for (int i = NX; i < NW; ++i) {
    if (hl[i] != 0.0) {
      dsl[i] = dz[i] + (z[i] - lb[i] - sl[i]);
      dll[i] = (tl[i] - ll[i] * (sl[i] + dsl[i])) / sl[i];
    }
    if (hu[i] != 0.0) {
      dsu[i] = -dz[i] + (ub[i] - z[i] - su[i]);
      dlu[i] = (tu[i] - lu[i] * (su[i] + dsu[i])) / su[i];
    }
  }
  return 0;
}

/* The dynamics' residual A_k x_k + B_k u_k + b_k - x_{k+1} of z into rd; returns its largest entry. */
static double dynamics_residual(const double* const* in, const double* z, double* rd) {
  double worst = 0.0;
  for (int k = 0; k < NH; ++k) {
    double* r = rd + k * NX;
    for (int i = 0; i < NX; ++i) r[i] = in[3][k * NX + i] - z[(k + 1) * NZ + i];
    for (int a = 0; a < NZ; ++a) {
      const double* col = &AB(in[2], k, 0, a);
      const double za = z[k * NZ + a];
      for (int i = 0; i < NX; ++i) r[i] += col[i] * za;
    }
    for (int i = 0; i < NX; ++i) worst = fmax(worst, fabs(r[i]));
  }
  return worst;
}

/* Complementarity s' lam / m of the iterate moved by alpha along the direction. */
static double complementarity(const double* v, double alpha, int count) {
  const double *sl = v + NW, *su = v + 2 * NW, *ll = v + 3 * NW, *lu = v + 4 * NW, *dsl = v + 10 * NW;
  const double *dsu = v + 11 * NW, *dll = v + 12 * NW, *dlu = v + 13 * NW, *hl = v + 14 * NW, *hu = v + 15 * NW;
  double s = 0.0;
  for (int i = NX; i < NW; ++i) {
    if (hl[i] != 0.0) s += (sl[i] + alpha * dsl[i]) * (ll[i] + alpha * dll[i]);
    if (hu[i] != 0.0) s += (su[i] + alpha * dsu[i]) * (lu[i] + alpha * dlu[i]);
  }
  return s / count;
}

/* The interior point from the equality-constrained solution z (in v). 1 on a failed factorisation. */
static int interior_point(const double* const* in, double* w, double* nu) {
  double* v = w + W_IPM;
  double *z = v, *sl = v + NW, *su = v + 2 * NW, *ll = v + 3 * NW, *lu = v + 4 * NW, *tl = v + 5 * NW;
  double *tu = v + 6 * NW, *dz = v + 9 * NW, *dsl = v + 10 * NW, *dsu = v + 11 * NW, *dll = v + 12 * NW;
  double *dlu = v + 13 * NW, *hl = v + 14 * NW, *hu = v + 15 * NW, *r = v + 16 * NW;
  const double *h = in[0], *g = in[1], *lb = in[4], *ub = in[5];
  int count = 0;
  for (int i = NX; i < NW; ++i) { /* slacks at least START_SLACK: the bounds' residuals vanish along the way */
    sl[i] = hl[i] != 0.0 ? fmax(z[i] - lb[i], START_SLACK) : 0.0;
    su[i] = hu[i] != 0.0 ? fmax(ub[i] - z[i], START_SLACK) : 0.0;
    ll[i] = hl[i] != 0.0 ? MU0 / sl[i] : 0.0;
    lu[i] = hu[i] != 0.0 ? MU0 / su[i] : 0.0;
    count += (hl[i] != 0.0) + (hu[i] != 0.0);
  }
  for (int i = 0; i < NX; ++i) w[W_RD + NB + i] = 0.0; /* dz of the fixed x_0 */
  dynamics_residual(in, z, w + W_RD);
  for (int it = 0; it < PSDM_QP_MAX_ITER; ++it) {
    const double mu = complementarity(v, 0.0, count);
    for (int i = 0; i < NW; ++i) tl[i] = tu[i] = 0.0; /* predictor: the affine direction */
    if (direction(in, w, 1)) break; /* the last iterate stands */
    double alpha = max_step(sl, dsl, hl, max_step(su, dsu, hu, max_step(ll, dll, hl, max_step(lu, dlu, hu, 1.0))));
    const double ratio = complementarity(v, alpha, count) / mu;
    const double target = ratio * ratio * ratio * mu;
    for (int i = NX; i < NW; ++i) { /* corrector: centring and the second-order term */
      tl[i] = hl[i] != 0.0 ? target - dsl[i] * dll[i] : 0.0;
      tu[i] = hu[i] != 0.0 ? target - dsu[i] * dlu[i] : 0.0;
    }
    direction(in, w, 0);
    alpha = max_step(sl, dsl, hl, max_step(su, dsu, hu, max_step(ll, dll, hl, max_step(lu, dlu, hu, 1.0 / STEP_TO_BOUNDARY))));
    alpha = fmin(1.0, STEP_TO_BOUNDARY * alpha);
    for (int i = NX; i < NW; ++i) {
      z[i] += alpha * dz[i];
      if (hl[i] != 0.0) sl[i] += alpha * dsl[i], ll[i] += alpha * dll[i];
      if (hu[i] != 0.0) su[i] += alpha * dsu[i], lu[i] += alpha * dlu[i];
    }
    const double gap = dynamics_residual(in, z, w + W_RD);
    for (int i = 0; i < NW; ++i) r[i] = h[i] * z[i] + g[i] - ll[i] + lu[i];
    const double stationarity = multipliers(r, in[2], nu);
    double bounds = 0.0; /* the bounds' residual (from the start's slacks) */
    for (int i = NX; i < NW; ++i) {
      if (hl[i] != 0.0) bounds = fmax(bounds, fabs(z[i] - lb[i] - sl[i]));
      if (hu[i] != 0.0) bounds = fmax(bounds, fabs(ub[i] - z[i] - su[i]));
    }
    const double worst = fmax(fmax(complementarity(v, 0.0, count), gap), fmax(stationarity, bounds));
    if (worst <= PSDM_QP_TOL || alpha < 1e-10) break; /* converged, or stalled in double precision */
  }
  for (int i = NX; i < NW; ++i) { /* an iterate short of the bounds' residual's end is held inside them */
    if (hl[i] != 0.0) z[i] = fmax(z[i], lb[i]);
    if (hu[i] != 0.0) z[i] = fmin(z[i], ub[i]);
  }
  return 0;
}

int PSDM_QP_NAME(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem) {
  (void)iw;
  (void)mem;
  const double* in[6] = {arg[0], arg[1], arg[2], arg[3], arg[4], arg[5]};
  double* v = w + W_IPM;
  double *z = v, *ll = v + 3 * NW, *lu = v + 4 * NW, *hl = v + 14 * NW, *hu = v + 15 * NW, *r = v + 16 * NW;
  if (factor(in[0], in[2], w)) return 1;
  solve(in[1], in[2], in[3], in[4], z, w);
  int inside = 1;
  for (int i = 0; i < NW; ++i) {
    hl[i] = i >= NX && isfinite(in[4][i]) ? 1.0 : 0.0;
    hu[i] = i >= NX && isfinite(in[5][i]) ? 1.0 : 0.0;
    ll[i] = lu[i] = 0.0;
    if ((hl[i] != 0.0 && z[i] < in[4][i]) || (hu[i] != 0.0 && z[i] > in[5][i])) inside = 0;
  }
  if (!inside && interior_point(in, w, w + W_NU)) return 1;
  if (res[0]) memcpy(res[0], z, NW * sizeof(double));
  if (res[1]) {
    for (int i = 0; i < NW; ++i) r[i] = in[0][i] * z[i] + in[1][i] - ll[i] + lu[i];
    multipliers(r, in[2], res[1]);
  }
  return 0;
}
