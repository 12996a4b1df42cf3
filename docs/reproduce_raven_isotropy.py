"""The isotropy-definition lever of Li et al.'s Fig. 7 and Table II (issue #26): eq. 35's Iso = 1/cond(J) taken
on eq. 41's 2 x 2 top-left block J_s (what the paper says it uses, and surgopt's default) or on the whole printed
3 x 3 matrix. Both depend on theta2 alone, so Iso_min still bounds theta2 only; what changes is which (alpha, beta)
can have any workspace at Iso_min = 0.5. Eq. 41 is written out here with numpy, apart from the kernels.

Run:  python docs/reproduce_raven_isotropy.py   (about 20 s; docs/reproduction.md quotes its output)
"""
import numpy as np


def jacobian_eq41(theta2, alpha, beta):
    """Eq. 41 as printed (left arm): columns theta1, theta2, d4 in frame 3."""
    s2, c2, sa, ca, sb, cb = np.sin(theta2), np.cos(theta2), np.sin(alpha), np.cos(alpha), np.sin(beta), np.cos(beta)
    return np.array([[c2 * cb * sa + sb * ca, -sb, 0.0], [s2 * sa, 0.0, 0.0], [c2 * sb * sa - cb * ca, cb, 1.0]])


def max_iso(alpha_deg, beta_deg, block):
    """The largest Iso over theta2 in (0, 180) deg (0.05 deg steps) and where, for one definition."""
    th = np.radians(np.arange(0.05, 180.0, 0.05))
    iso = []
    for t in th:
        j = jacobian_eq41(t, np.radians(alpha_deg), np.radians(beta_deg))
        j = j[:2, :2] if block == "2x2" else j
        s = np.linalg.svd(j, compute_uv=False)
        iso.append(s[-1] / s[0])
    k = int(np.argmax(iso))
    return iso[k], np.degrees(th[k])


def main() -> None:
    print("| (alpha, beta) | why | max Iso, 2 x 2 block (at theta2) | max Iso, 3 x 3 (at theta2) |")
    print("|---|---|---|---|")
    for ab, why in (((80, 40), "Fig. 7a argmax"), ((70, 35), "Fig. 7b argmax"), ((85, 65), "Table II optimum"),
                    ((75, 60), "our Fig. 7b argmax")):
        (i2, t2), (i3, t3) = max_iso(*ab, "2x2"), max_iso(*ab, "3x3")
        print(f"| {ab[0]}°, {ab[1]}° | {why} | {i2:.3f} ({t2:.1f}°) | {i3:.3f} ({t3:.1f}°) |")
    grid = [(a, b) for a in range(5, 91, 5) for b in range(5, 91, 5)]
    for block in ("2x2", "3x3"):
        ok = [(a, b) for a, b in grid if max_iso(a, b, block)[0] >= 0.5]
        lo_a, lo_b = (min(v[i] for v in ok) for i in (0, 1)) if ok else (None, None)
        print(f"{block}: {len(ok)} of {len(grid)} (alpha, beta) pairs on Fig. 7's 5-deg grid have some theta2 with "
              f"Iso >= 0.5, which a node at Iso_min = 0.5 needs (smallest alpha {lo_a}, smallest beta {lo_b})")


if __name__ == "__main__":
    main()
