// The linear posture model solved in the page (docs/studio.md, "Solving in the page"): the
// same box-constrained quadratic programme as PostureSolver::solve_linear (src/posture/
// solver.cpp), over the potential ½xᵀHx − gᵀx + c that GET /api/system sends, and the joints
// posed as Skeleton::frames does (src/posture/skeleton.cpp), on skin.glb's own rest nodes.
// Written here rather than taken from a package: it is 35 unknowns, a dense Cholesky and an
// active set, and it must match the server's solver to the last digit (the end-to-end test
// compares them).
import * as THREE from 'three';

// Cholesky factor of the n × n symmetric positive definite matrix a (row-major), or null.
function cholesky(a, n) {
  const l = new Float64Array(n * n);
  for (let i = 0; i < n; ++i)
    for (let j = 0; j <= i; ++j) {
      let s = a[i * n + j];
      for (let k = 0; k < j; ++k) s -= l[i * n + k] * l[j * n + k];
      if (i === j) {
        if (!(s > 0)) return null;
        l[i * n + i] = Math.sqrt(s);
      } else l[i * n + j] = s / l[j * n + j];
    }
  return l;
}
function choleskySolve(l, n, b) {
  const y = new Float64Array(n);
  for (let i = 0; i < n; ++i) {
    let s = b[i];
    for (let k = 0; k < i; ++k) s -= l[i * n + k] * y[k];
    y[i] = s / l[i * n + i];
  }
  for (let i = n - 1; i >= 0; --i) {
    let s = y[i];
    for (let k = i + 1; k < n; ++k) s -= l[k * n + i] * y[k];
    y[i] = s / l[i * n + i];
  }
  return y;
}

export class LinearPostureSolver {
  // sys: one parameter set of GET /api/system; names: the DOF names in canonical order.
  constructor(sys, names) {
    if (!sys.linear) throw new Error('this parameter set is not linear: it is solved by the server');
    this.n = names.length;
    this.names = names;
    this.H = Float64Array.from(sys.H);
    this.g = Float64Array.from(sys.g);
    this.c = sys.c;
    this.relaxed = sys.relaxed;
    this.lo = sys.lo;
    this.hi = sys.hi;
    this.index = Object.fromEntries(names.map((name, i) => [name, i]));
    this.factors = new Map();  // the free DOFs' Cholesky factor per set of fixed DOFs
  }

  factor(fixed) {
    const key = fixed.join('');
    let f = this.factors.get(key);
    if (f) return f;
    const free = [];
    for (let d = 0; d < this.n; ++d) if (!fixed[d]) free.push(d);
    const m = free.length, a = new Float64Array(m * m);
    for (let r = 0; r < m; ++r) for (let c = 0; c < m; ++c) a[r * m + c] = this.H[free[r] * this.n + free[c]];
    const l = cholesky(a, m);
    if (!l) throw new Error('posture system is not positive definite');
    f = { free, l };
    if (this.factors.size < 4096) this.factors.set(key, f);
    return f;
  }

  // inputs: {DOF name: degrees} pinned (clamped onto the limits, as the server's pose does);
  // torques: {DOF name: instructed input}. Returns {angles: {name: deg}, energy, rounds}.
  solve(inputs = {}, torques = {}) {
    const n = this.n, H = this.H;
    const x = Float64Array.from(this.relaxed), g = Float64Array.from(this.g);
    const fixed = new Uint8Array(n), pinned = new Uint8Array(n), side = new Int8Array(n);
    for (const [name, v] of Object.entries(inputs)) {
      const d = this.index[name];
      if (d === undefined || !Number.isFinite(v)) throw new Error(`bad input ${name}=${v}`);
      x[d] = Math.min(Math.max(v, this.lo[d]), this.hi[d]);
      fixed[d] = pinned[d] = 1;
    }
    for (const [name, t] of Object.entries(torques)) {
      const d = this.index[name];
      if (d === undefined || !Number.isFinite(t)) throw new Error(`bad torque ${name}=${t}`);
      g[d] += t;
    }
    let rounds = 0;
    for (;;) {
      if (++rounds > 4 * n) throw new Error('posture active set did not settle');
      const { free, l } = this.factor(fixed);
      const rhs = new Float64Array(free.length);
      free.forEach((i, r) => {
        let v = g[i];
        for (let j = 0; j < n; ++j) if (fixed[j]) v -= H[i * n + j] * x[j];
        rhs[r] = v;
      });
      const y = choleskySolve(l, free.length, rhs);
      free.forEach((i, r) => { x[i] = y[r]; });
      // Free DOFs beyond a limit join the active set at that limit.
      let added = false;
      for (const i of free) {
        if (x[i] < this.lo[i] - 1e-9) { side[i] = -1; x[i] = this.lo[i]; fixed[i] = 1; added = true; }
        else if (x[i] > this.hi[i] + 1e-9) { side[i] = 1; x[i] = this.hi[i]; fixed[i] = 1; added = true; }
      }
      if (added) continue;
      // KKT: a DOF held at a limit must be pushed against it; release the worst one that is not.
      let worst = -1, worstV = 1e-9;
      for (let i = 0; i < n; ++i) {
        if (!side[i]) continue;
        let grad = -g[i];
        for (let j = 0; j < n; ++j) grad += H[i * n + j] * x[j];
        const v = side[i] < 0 ? -grad : grad;
        if (v > worstV) { worstV = v; worst = i; }
      }
      if (worst < 0) break;
      side[worst] = 0;
      fixed[worst] = 0;
    }
    // The potential (springs, pairs and constraints, less the torques' work), as the server's.
    let e = this.c;
    for (let i = 0; i < n; ++i) {
      let hx = 0;
      for (let j = 0; j < n; ++j) hx += H[i * n + j] * x[j];
      e += 0.5 * x[i] * hx - this.g[i] * x[i];
    }
    for (const [name, t] of Object.entries(torques)) e -= t * x[this.index[name]];
    const angles = {};
    this.names.forEach((name, i) => { angles[name] = x[i]; });
    return { angles, energy: e, rounds };
  }
}

// The joints posed from angles, on skin.glb's bones, from the rest transforms the server sends
// (a posed glb's nodes are not at rest):
// a finger joint turns by Rz(sign · abduction) · Rx(flexion) in its rest frame; the carpus by
// Rz · Ry · Rx of its three rotations and moves by its three translations (mm, in the palm frame).
const X = new THREE.Vector3(1, 0, 0), Y = new THREE.Vector3(0, 1, 0), Z = new THREE.Vector3(0, 0, 1);
const RAD = Math.PI / 180;
export class JointPoser {
  constructor(joints, bones, names) {
    this.joints = joints.map(j => ({ ...j, bone: bones[j.name] }));
    for (const j of this.joints) {
      if (!j.bone) throw new Error(`skin.glb has no joint ${j.name}`);
      j.restQ = new THREE.Quaternion(...j.rest.q);
      j.restT = new THREE.Vector3(...j.rest.t);
    }
    this.names = names;
    this.q = new THREE.Quaternion();
  }
  // angles: {DOF name: value}; sets every bone's local transform.
  apply(angles) {
    const a = this.names.map(n => angles[n] ?? 0);
    const q = this.q;
    this.joints.forEach((j, k) => {
      if (k === 0) {
        j.bone.position.set(j.restT.x + a[0] / 1000, j.restT.y + a[1] / 1000, j.restT.z + a[2] / 1000);
        j.bone.quaternion.copy(j.restQ)
          .multiply(q.setFromAxisAngle(Z, a[5] * RAD))
          .multiply(q.setFromAxisAngle(Y, a[4] * RAD))
          .multiply(q.setFromAxisAngle(X, a[3] * RAD));
        return;
      }
      j.bone.quaternion.copy(j.restQ);
      if (j.flex >= 0) {
        if (j.abd >= 0) j.bone.quaternion.multiply(q.setFromAxisAngle(Z, j.abd_sign * a[j.abd] * RAD));
        j.bone.quaternion.multiply(q.setFromAxisAngle(X, a[j.flex] * RAD));
      }
    });
  }
}
