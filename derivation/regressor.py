"""Symbolic derivation of the PRRRP dynamics and of the full 5x8 regressor.

Paper Annex B prints only the first entries of the regressor; this script derives all of
them, reproducibly:

1. It writes the Lagrangian from the physical description (link masses, centre-of-mass
   positions, inertias about the centre of mass; see shared/notes/paper.md), independently
   of any parameter grouping, and derives the equations of motion by Euler-Lagrange.
2. It writes the same Lagrangian in the 8 grouped parameters lambda (Table 3, corrected),
   checks that both are identical after substituting lambda(physical), and checks that the
   equations of motion agree.
3. It derives Phi = d tau / d lambda from the grouped form (tau is linear in lambda) and
   prints every entry, in the notation of crates/prrrp-core/src/models/prrrp/regressor.rs.
4. It checks the printed Annex A / Annex B entries that survived extraction, with the typos
   of the notes corrected, against the derived model.

Usage:  python derivation/regressor.py      (needs sympy)
Exit code 0 when every check passes.
"""

import sympy as sp

t = sp.symbols("t")
g = sp.symbols("g", positive=True)
m1, m2, m3, m4, m5 = sp.symbols("m1:6", positive=True)
l2, l3, l4 = sp.symbols("l2 l3 l4", positive=True)
lc2, lc3, lc4 = sp.symbols("lc2 lc3 lc4", positive=True)
I2, I3, I4 = sp.symbols("I2zz I3zz I4zz", positive=True)
lam = sp.symbols("lambda1:9")

d1, th2, th3, th4, d5 = [sp.Function(n)(t) for n in ("d1", "theta2", "theta3", "theta4", "d5")]
q = [d1, th2, th3, th4, d5]
qd = [sp.diff(x, t) for x in q]
qdd = [sp.diff(x, t, 2) for x in q]


def lagrange(lagrangian):
    return [sp.expand(sp.diff(sp.diff(lagrangian, v), t) - sp.diff(lagrangian, x)) for x, v in zip(q, qd)]


# --- 1. physical Lagrangian --------------------------------------------------------------
phi2, phi3, phi4 = th2, th2 + th3, th2 + th3 + th4  # absolute link angles in the plane
j3 = sp.Matrix([l2 * sp.cos(phi2), l2 * sp.sin(phi2)])  # joint 3 in the plane
j4 = j3 + sp.Matrix([l3 * sp.cos(phi3), l3 * sp.sin(phi3)])
tip = j4 + sp.Matrix([l4 * sp.cos(phi4), l4 * sp.sin(phi4)])
com2 = sp.Matrix([lc2 * sp.cos(phi2), lc2 * sp.sin(phi2)])
com3 = j3 + sp.Matrix([lc3 * sp.cos(phi3), lc3 * sp.sin(phi3)])
com4 = j4 + sp.Matrix([lc4 * sp.cos(phi4), lc4 * sp.sin(phi4)])


def speed2(planar, z):
    v = planar.diff(t)
    return sp.expand((v.T * v)[0] + sp.diff(z, t) ** 2)


# Links 1-4 move vertically with d1; the tool (point mass m5) hangs at the tip and moves
# along -z with d5 (DH alpha4 = 180 deg). Heights are up to a constant.
T_phys = (
    m1 * sp.diff(d1, t) ** 2 / 2
    + m2 * speed2(com2, d1) / 2 + I2 * sp.diff(phi2, t) ** 2 / 2
    + m3 * speed2(com3, d1) / 2 + I3 * sp.diff(phi3, t) ** 2 / 2
    + m4 * speed2(com4, d1) / 2 + I4 * sp.diff(phi4, t) ** 2 / 2
    + m5 * speed2(tip, d1 - d5) / 2
)
U_phys = g * ((m1 + m2 + m3 + m4) * d1 + m5 * (d1 - d5))
tau_phys = lagrange(T_phys - U_phys)

# --- 2. grouped Lagrangian -----------------------------------------------------------------
lam_of_phys = {
    lam[0]: m1 + m2 + m3 + m4,
    lam[1]: m2 * lc2**2 + (m3 + m4 + m5) * l2**2 + I2,
    lam[2]: m3 * lc3**2 + (m4 + m5) * l3**2 + I3,
    lam[3]: l2 * (m3 * lc3 + (m4 + m5) * l3),
    lam[4]: m4 * lc4**2 + m5 * l4**2 + I4,
    lam[5]: l2 * (m4 * lc4 + m5 * l4),
    lam[6]: l3 * (m4 * lc4 + m5 * l4),
    lam[7]: m5,
}
w2, w3, w4 = [sp.diff(p, t) for p in (phi2, phi3, phi4)]
T_lam = (
    lam[0] * sp.diff(d1, t) ** 2 / 2
    + lam[7] * (sp.diff(d1, t) - sp.diff(d5, t)) ** 2 / 2
    + lam[1] * w2**2 / 2 + lam[2] * w3**2 / 2 + lam[4] * w4**2 / 2
    + lam[3] * w2 * w3 * sp.cos(th3)
    + lam[5] * w2 * w4 * sp.cos(th3 + th4)
    + lam[6] * w3 * w4 * sp.cos(th4)
)
U_lam = g * (lam[0] * d1 + lam[7] * (d1 - d5))
tau_lam = lagrange(T_lam - U_lam)

failures = []


def is_zero(expr):
    if isinstance(expr, sp.MatrixBase):
        return all(is_zero(e) for e in expr)
    e = sp.expand(sp.expand_trig(sp.expand(expr)))
    # Only the energy needs sin^2 + cos^2 = 1; the cheap expansion settles the rest.
    return e == 0 or sp.simplify(e) == 0


def check(name, expr):
    if not is_zero(expr):
        failures.append(name)
        print(f"FAIL {name}: {sp.simplify(expr)}")


check("T(physical) == T(lambda)", T_phys - T_lam.subs(lam_of_phys))
for i in range(5):
    check(f"tau{i + 1}(physical) == tau{i + 1}(lambda)", tau_phys[i] - tau_lam[i].subs(lam_of_phys))

# --- 3. the regressor ------------------------------------------------------------------------
names = ["dd1", "ddth2", "ddth3", "ddth4", "dd5", "dth2", "dth3", "dth4", "dd1_", "dd5_"]
pretty = {}
for i, x in enumerate(q):
    pretty[sp.diff(x, t, 2)] = sp.Symbol(["d1dd", "th2dd", "th3dd", "th4dd", "d5dd"][i])
    pretty[sp.diff(x, t)] = sp.Symbol(["d1d", "th2d", "th3d", "th4d", "d5d"][i])
    pretty[x] = sp.Symbol(["d1", "th2", "th3", "th4", "d5"][i])

Phi = sp.Matrix(5, 8, lambda i, j: sp.diff(tau_lam[i], lam[j]))
assert sp.expand(Phi * sp.Matrix(lam) - sp.Matrix(tau_lam)) == sp.zeros(5, 1), "tau not linear in lambda"
print("Regressor Phi (tau = Phi * lambda); rows F1, tau2, tau3, tau4, F5; columns lambda1..8")
for i in range(5):
    for j in range(8):
        e = sp.simplify(Phi[i, j].subs(pretty))
        if e != 0:
            print(f"  Phi[{i + 1},{j + 1}] = {sp.factor_terms(e)}")

# --- 4. the entries printed in the paper (typos corrected) ------------------------------------
s3, c3, s4, c4 = sp.sin(th3), sp.cos(th3), sp.sin(th4), sp.cos(th4)
s34, c34 = sp.sin(th3 + th4), sp.cos(th3 + th4)
D = [sp.diff(x, t) for x in q]
A = [sp.diff(x, t, 2) for x in q]
MX3 = lc3 * m3 + l3 * m4 + l3 * m5
MX4 = lc4 * m4 + l4 * m5
# Mass matrix from the physical model: d tau / d qdd.
M = sp.Matrix(5, 5, lambda i, j: sp.diff(tau_phys[i], A[j]))
printed_M = {
    (0, 0): m1 + m2 + m3 + m4 + m5,  # A.1
    (0, 4): -m5,  # A.3
    (3, 3): lc4**2 * m4 + l4**2 * m5 + I4,  # A.9
    (4, 4): m5,  # A.10
    (1, 1): lc2**2 * m2 + (l2**2 + lc3**2 + 2 * l2 * lc3 * c3) * m3  # A.4
    + (l2**2 + l3**2 + lc4**2 + 2 * l2 * l3 * c3) * m4 + 2 * (l3 * lc4 * c4 + l2 * lc4 * c34) * m4
    + (l2**2 + l3**2 + l4**2 + 2 * l2 * l3 * c3) * m5 + 2 * (l3 * l4 * c4 + l2 * l4 * c34) * m5
    + I2 + I3 + I4,
    (1, 2): (lc3**2 + l2 * lc3 * c3) * m3  # A.5
    + (l3**2 + lc4**2 + l2 * l3 * c3 + 2 * l3 * lc4 * c4) * m4 + l2 * lc4 * c34 * m4
    + l2 * l4 * c34 * m5 + (l3**2 + l4**2 + l2 * l3 * c3 + 2 * l3 * l4 * c4) * m5 + I3 + I4,
    (1, 3): (lc4**2 + l3 * lc4 * c4 + l2 * lc4 * c34) * m4  # A.6
    + (l4**2 + l3 * l4 * c4 + l2 * l4 * c34) * m5 + I4,
    (2, 2): lc3**2 * m3 + (l3**2 + lc4**2 + 2 * l3 * lc4 * c4) * m4  # A.7
    + (l3**2 + l4**2 + 2 * l3 * l4 * c4) * m5 + I3 + I4,
    (2, 3): (lc4**2 + l3 * lc4 * c4) * m4 + (l4**2 + l3 * l4 * c4) * m5 + I4,  # A.8
}
for (i, j), e in printed_M.items():
    check(f"Annex A M{i + 1}{j + 1}", M[i, j] - e)
for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 4), (2, 4), (3, 4)]:
    check(f"Annex A.2 M{i + 1}{j + 1} = 0", M[i, j])

zero_acc = {a: 0 for a in A}
h = [sp.expand(tau_phys[i].subs(zero_acc)) for i in range(5)]  # C(q, qd) qd + G
G = [sp.expand(tau_phys[i].subs(zero_acc).subs({d: 0 for d in D})) for i in range(5)]
C = [sp.expand(h[i] - G[i]) for i in range(5)]
check("A.15 G", sp.Matrix(G) - sp.Matrix([(m1 + m2 + m3 + m4 + m5) * g, 0, 0, 0, -m5 * g]))
check("A.11 C1 = 0", C[0])
check("A.11 C5 = 0", C[4])
# A.12 with typo 1 corrected: coefficient 2 on the s34*th2d*th3d term, every term negative.
C12 = -(l2 * s3 * D[2] ** 2 + 2 * l2 * s3 * D[1] * D[2]) * MX3 - (
    l2 * s34 * D[2] ** 2 + 2 * (l3 * s4 + l2 * s34) * D[2] * D[3]
) * MX4 - (2 * l2 * s34 * D[1] * D[2] + (D[3] ** 2 + 2 * D[1] * D[3]) * (l2 * s34 + l3 * s4)) * MX4
check("A.12 C2 (coefficient 2 restored)", C[1] - C12)
C14 = MX4 * (l3 * s4 + l2 * s34) * D[1] ** 2 + (l3 * s4 * D[2] ** 2 + 2 * l3 * s4 * D[1] * D[2]) * MX4
check("A.14 C4", C[3] - C14)
# Annex B entries that survived extraction.
check("B.3 phi11", Phi[0, 0] - (A[0] + g))
check("B.4 phi1,8", Phi[0, 7] - (A[0] - A[4] + g))
check("B.5 phi22", Phi[1, 1] - A[1])
check("B.6 phi2,4", Phi[1, 3] - ((2 * A[1] + A[2]) * c3 - (2 * D[1] * D[2] + D[2] ** 2) * s3))

if failures:
    print(f"{len(failures)} check(s) failed")
    raise SystemExit(1)
print("all checks passed: physical and grouped models agree, printed Annex A/B entries hold")
