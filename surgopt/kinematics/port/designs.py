"""Port placement's designs: the per-port and per-pair tables (``place``) combined into one row per
design of two or three instrument ports and a camera port, every port distinct, at a few operations per
design (issue #29). Numba kernels and the numpy helpers that pack their tables. One module (~410 lines):
the kernels and the packing of their bit tables share one layout of words and bits, which must not drift apart."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from surgopt.jit import EXACT, njit
from surgopt.kinematics.port import columns as C
from surgopt.kinematics.port.capsules import PAIR_CODE
from surgopt.kinematics.port.reasons import ANGLE, CAMERA, CAMERA_SIDE, DOCKING, OUTSIDE, REACH, SHAFTS, SPACING


class PortTables(NamedTuple):
    """What ``design_columns`` combines (from ``instrument_tables``, ``camera_coverage``, ``pair_tables``,
    ``camera_pair_tables``, plus port distances, each site's reach as bits and its mean isotropy)."""

    reach_count: np.ndarray  # per site: target points the instrument reaches
    coverage: np.ndarray  # per site: share of target points the camera sees
    count: np.ndarray  # per pair i < j
    dex_mean: np.ndarray
    ang_mean: np.ndarray
    ang_min: np.ndarray
    ang_max: np.ndarray
    ang_share: np.ndarray
    ang_centre: np.ndarray
    inside: np.ndarray
    outside: np.ndarray  # instrument arms, per pair i < j
    spacing: np.ndarray  # port-to-port distance, every pair
    azimuth: np.ndarray  # [instrument port, camera port]
    side: np.ndarray
    n_points: int
    reach_bits: np.ndarray  # per site: the reached target points, 64 to a uint64 word (``reach_bits``)
    dex_site: np.ndarray  # per site: the mean isotropy over the points it reaches (0 where it reaches none)
    wrist_margin_deg: np.ndarray  # per site: the wrist's bend left at the worst point (the study's, for its rows)
    outside_camera: np.ndarray  # [instrument port, camera port]: the two arms' clearance outside the body
    dock: np.ndarray  # (3, sites, words) uint64: bit p set where PSM1's, PSM2's, PSM3's setup joints dock at cart pose p
    dock_camera: np.ndarray  # (sites, words) uint64: the ECM's
    # the arms' links outside the body with the cart (``studies/port_place/link_tables``; none: 0 pairs), per arm
    # pair (PSM1-PSM2, PSM1-ECM, PSM2-ECM, then with PSM3: PSM1-PSM3, PSM2-PSM3, PSM3-ECM), the first arm's site,
    # the second's, and the cart pose: whether they clear (words), the least clearance (m) and its link pair
    link_words: np.ndarray = np.ones((0, 1, 1, 1), np.uint64)
    link_value: np.ndarray = np.zeros((0, 1, 1, 1), np.float32)
    link_code: np.ndarray = np.zeros((0, 1, 1, 1), np.int16)
    # each arm (PSM1, PSM2, PSM3, ECM) against the patient and the table at (site, pose), the same three ways
    arm_words: np.ndarray = np.ones((0, 1, 1), np.uint64)
    arm_value: np.ndarray = np.zeros((0, 1, 1), np.float32)
    arm_code: np.ndarray = np.zeros((0, 1, 1), np.int16)
    # per site: the instrument's docking roll about its neutral shaft, deg (the study's, for its rows)
    roll_deg: np.ndarray = np.zeros(0)
    # per site, the third instrument's own reach and mean isotropy where it docks in a frame of its own (the Si
    # PSM3: ``studies/port_place/tables.si_frames``); none (0 sites): the third's are the first two's, above
    third_reach_count: np.ndarray = np.zeros(0, np.int64)
    third_reach_bits: np.ndarray = np.zeros((0, 1), np.uint64)
    third_dex_site: np.ndarray = np.zeros(0)
    # per site: the endoscope's tip where it is held (``place.camera_views``), its depth past the RCM along the
    # shaft and its distance to the target's centre, mm (NaN where the scope cannot be placed; the study's rows)
    camera_tip_depth_mm: np.ndarray = np.zeros(0)
    camera_tip_to_centre_mm: np.ndarray = np.zeros(0)
    # per site: the tip itself (m, patient frame) and its unit view axis (NaN where the scope cannot be placed)
    camera_tip_m: np.ndarray = np.zeros((0, 3))
    camera_axis: np.ndarray = np.zeros((0, 3))


def reach_bits(reach: np.ndarray) -> np.ndarray:
    """reach[site, point] (bool) packed 64 points to a uint64 word, point k in bit k % 64 of word k // 64."""
    n, m = reach.shape
    padded = np.zeros((n, -(-m // 64) * 64), dtype=np.bool_)
    padded[:, :m] = reach
    return np.packbits(padded, axis=1, bitorder="little").view("<u8").astype(np.uint64)


def pack_bits(ok: np.ndarray) -> np.ndarray:
    """ok[..., pose] (bool) as uint64 words, pose p in bit p % 64 of word p // 64."""
    m = ok.shape[-1]
    padded = np.zeros(ok.shape[:-1] + (-(-m // 64) * 64,), dtype=np.bool_)
    padded[..., :m] = ok
    return np.packbits(padded, axis=-1, bitorder="little").view("<u8").astype(np.uint64)


def site_dexterity(reach: np.ndarray, dex: np.ndarray) -> np.ndarray:
    """Each site's mean isotropy over the target points it reaches (0 where it reaches none)."""
    count = reach.sum(axis=1)
    return np.where(count > 0, (dex * reach).sum(axis=1) / np.maximum(count, 1), 0.0)


_M1, _M2, _M4, _H01 = (np.uint64(0x5555555555555555), np.uint64(0x3333333333333333), np.uint64(0x0F0F0F0F0F0F0F0F),
                       np.uint64(0x0101010101010101))
_S1, _S2, _S4, _S56 = np.uint64(1), np.uint64(2), np.uint64(4), np.uint64(56)


@njit(**EXACT)
def popcount64(x):
    """The set bits of a uint64 word (the SWAR count: Warren, Hacker's Delight, 2nd ed., Fig. 5-2)."""
    x = x - ((x >> _S1) & _M1)
    x = (x & _M2) + ((x >> _S2) & _M2)
    x = (x + (x >> _S4)) & _M4
    return (x * _H01) >> _S56


@njit(**EXACT)
def pair_of(index, n):
    """The (i, j), i < j, of the ``index``-th pair in the order (0,1), (0,2) ... (0,n-1), (1,2) ..."""
    i = 0
    left = index
    while left >= n - 1 - i:
        left -= n - 1 - i
        i += 1
    return i, i + 1 + left


@njit(**EXACT)
def nth_other(rank, a, b, c):
    """The ``rank``-th site (from 0, ascending) that is none of a, b and c (c < 0: none of a and b)."""
    lo, hi = min(a, b), max(a, b)
    x = rank
    if c < 0:
        if x >= lo:
            x += 1
        if x >= hi:
            x += 1
        return x
    s0, s2 = min(lo, c), max(hi, c)
    s1 = a + b + c - s0 - s2
    if x >= s0:
        x += 1
    if x >= s1:
        x += 1
    if x >= s2:
        x += 1
    return x


@njit(**EXACT)
def at(a, i, j):
    """A pair table's entry for sites i and j in either order (the tables fill i < j)."""
    return a[min(i, j), max(i, j)]


@njit(**EXACT)
def design_columns(t, crit, start, stop, instruments=2, feasible_only=False):
    """Designs ``start`` .. ``stop`` - 1 of ``instruments`` (2 or 3) instrument arms and the camera. Design d is
    working pair p = d // per_pair (``pair_of``: PSM1 and PSM2, the surgeon's two hands, unordered), then with
    three instruments the third's port (the r-th site that is neither, r = (d mod per_pair) // (n - 3)), then
    the camera's port (the next rank among the sites left, ``nth_other``); per_pair = (n - 2) or
    (n - 2)(n - 3). Decoded once at ``start``, then stepped (``next_other``).

    The pair's quantities (manipulation angle, azimuths, the camera between them, dexterity) are the working
    pair's; with a third instrument the common reach is all three's, the shafts' clearance inside is the least
    of the three pairs', the arms' outside and the ports' spacing the least of every pair's, and the cost adds
    the third's isotropy shortfall. A design no cart pose docks (``first_dock``) fails on DOCKING. Returns (ids
    [PSM1, PSM2, (PSM3,) ECM], columns, reason bits, cost, design numbers, (cart pose, PSM1 and PSM2 swapped,
    the links' least pair or -1))
    of every design, or of the feasible ones only (``feasible_only``: the rows of the others are
    never written, so a chunk's memory is its feasible rows').
    (docs/port_placement.md, eq. P11: the cost and feasibility.)"""
    n = t.reach_count.shape[0]
    three = instruments == 3
    own = t.third_reach_count.shape[0] > 0  # the third docks in frames of its own
    reach3 = t.third_reach_count if own else t.reach_count
    bits3 = t.third_reach_bits if own else t.reach_bits
    dex3 = t.third_dex_site if own else t.dex_site
    size = stop - start
    ids = np.empty((size, 4 if three else 3), dtype=np.int64)
    f = np.empty((size, C.THREE_INSTRUMENTS if three else C.TWO_INSTRUMENTS))
    bad = np.empty(size, dtype=np.int64)
    cost = np.empty(size)
    design = np.empty(size, dtype=np.int64)
    dock = np.empty((size, 3), dtype=np.int64)
    others = n - 3 if three else n - 2
    per_pair = (n - 2) * others if three else others
    i, j = pair_of(start // per_pair, n)
    rest = start % per_pair
    if three:
        l = nth_other(rest // others, i, j, -1)
        k = nth_other(rest % others, i, j, l)
    else:
        l = -1
        k = nth_other(rest, i, j, -1)
    out = 0
    for r in range(size):
        imbalance = abs(t.azimuth[i, k] - t.azimuth[j, k])
        spacing = min(t.spacing[i, j], min(t.spacing[i, k], t.spacing[j, k]))
        outside = min(t.outside[i, j], min(t.outside_camera[i, k], t.outside_camera[j, k]))
        inside = t.inside[i, j]
        if three:
            # the points all three reach: the pair's count when the third reaches every point, the third's
            # when the pair does, else the set bits of the three sites' reach_bits ANDed (written out here:
            # a call taking the tables' arrays pays a reference count for each, ~60 ns a design)
            if reach3[l] == t.n_points:
                c3 = t.count[i, j]
            elif t.count[i, j] == t.n_points:
                c3 = reach3[l]
            else:
                c3 = 0
                for w in range(t.reach_bits.shape[1]):
                    c3 += np.int64(popcount64(t.reach_bits[i, w] & t.reach_bits[j, w] & bits3[l, w]))
            common = c3 / t.n_points
            spacing = min(spacing, min(t.spacing[i, l], min(t.spacing[j, l], t.spacing[l, k])))
            outside = min(outside, min(at(t.outside, i, l), min(at(t.outside, j, l), t.outside_camera[l, k])))
            inside = min(inside, min(at(t.inside, i, l), at(t.inside, j, l)))
        else:
            common = t.count[i, j] / t.n_points
        # how far the optical axis is off the arc between the instruments (0 when it lies between them, in
        # their plane; spherical triangle inequality: azimuth_i + azimuth_j >= their angle)
        off_arc = max(0.0, t.azimuth[i, k] + t.azimuth[j, k] - t.ang_centre[i, j])
        b = 0
        if common < 1.0:
            b |= REACH
        if t.coverage[k] < 1.0:
            b |= CAMERA
        if spacing < crit.min_spacing_m:
            b |= SPACING
        if inside < crit.min_shaft_gap_m:
            b |= SHAFTS
        links = t.link_words.shape[0] > 0
        if outside < crit.min_external_m and not links:
            b |= OUTSIDE
        if not (crit.angle_lo_rad <= t.ang_centre[i, j] <= crit.angle_hi_rad):
            b |= ANGLE
        if t.side[i, k] * t.side[j, k] >= 0.0:
            b |= CAMERA_SIDE
        pose, swapped = first_dock(t.dock, t.dock_camera, i, j, l, k)
        code = -1
        if links:
            outside = np.nan  # the links are not placed: no pose docks, or the design fails on another count
        if pose < 0:
            b |= DOCKING
        elif links and b == 0:  # of the dockings whose links clear, the one that clears most (the pose of the most
            # margin, issue 54, not the first found), else OUTSIDE at the docking that clears most (only for designs
            # that pass every other check: the tables hold the entries they need)
            clear, turned = clearest_clear(t, i, j, l, k)
            if clear >= 0:
                pose, swapped = clear, turned
            else:
                b |= OUTSIDE
                pose, swapped = clearest_docking(t, i, j, l, k)
            outside, code = links_at(t, i, j, l, k, pose, swapped)
        if b == 0 or not feasible_only:
            ids[out, 0], ids[out, 1], ids[out, ids.shape[1] - 1] = i, j, k
            f[out, C.REACH_1] = t.reach_count[i] / t.n_points
            f[out, C.REACH_2] = t.reach_count[j] / t.n_points
            f[out, C.COMMON_REACH] = common
            f[out, C.DEXTERITY_MEAN] = t.dex_mean[i, j]
            f[out, C.ANGLE_MEAN] = t.ang_mean[i, j]
            f[out, C.ANGLE_MIN] = t.ang_min[i, j]
            f[out, C.ANGLE_MAX] = t.ang_max[i, j]
            f[out, C.ANGLE_SHARE] = t.ang_share[i, j]
            f[out, C.ANGLE_CENTRE] = t.ang_centre[i, j]
            f[out, C.AZIMUTH_IMBALANCE] = imbalance
            f[out, C.CAMERA_COVERAGE] = t.coverage[k]
            f[out, C.SHAFT_CLEARANCE] = inside
            f[out, C.EXTERNAL_CLEARANCE] = outside
            f[out, C.CAMERA_OFF_ARC] = off_arc
            f[out, C.PORT_SPACING] = spacing
            bad[out] = b
            cost[out] = (crit.w_reach * (1.0 - common) + crit.w_angle * abs(t.ang_mean[i, j] - crit.angle_best_rad)
                         + crit.w_azimuth * (imbalance + off_arc) + crit.w_camera * (1.0 - t.coverage[k])
                         + crit.w_dexterity * (1.0 - t.dex_mean[i, j]))
            if three:
                ids[out, 2] = l
                f[out, C.REACH_3] = reach3[l] / t.n_points
                f[out, C.DEXTERITY_3] = dex3[l]
                cost[out] += crit.w_dexterity * (1.0 - dex3[l])
            design[out] = start + r
            dock[out, 0], dock[out, 1], dock[out, 2] = pose, swapped, code
            out += 1
        k = next_other(k, i, j, l)  # the next camera port; then the next third port; then the next pair
        if k == n:
            if three:
                l = next_other(l, i, j, -1)
            if l == n or not three:
                j += 1
                if j == n:
                    i += 1
                    j = i + 1
                l = next_other(-1, i, j, -1) if three else -1
            k = next_other(-1, i, j, l)
    return ids[:out], f[:out], bad[:out], cost[:out], design[:out], dock[:out]


@njit(**EXACT)
def first_dock(dock, dock_camera, i, j, l, k):
    """(the first cart pose at which the setup joints dock PSM1 and PSM2 on the pair's ports i, j (either way
    round), PSM3 on l (l < 0: no third) and the ECM on k, or -1; 1 when PSM1 docks on j and PSM2 on i there,
    else 0): the lowest bit of their words ANDed, the straight assignment preferred at that pose."""
    for w in range(dock.shape[2]):
        straight, crossed = docking_words(dock, dock_camera, i, j, l, k, w)
        if (straight | crossed) != 0:
            return lowest_pose(w, straight, crossed)
    return -1, 0


@njit(**EXACT)
def docking_words(dock, dock_camera, i, j, l, k, w):
    """Word w of the cart poses at which every arm docks, PSM1 on i and PSM2 on j (straight) or the other way
    round (crossed)."""
    both = dock_camera[k, w]
    if l >= 0:
        both &= dock[2, l, w]
    return dock[0, i, w] & dock[1, j, w] & both, dock[0, j, w] & dock[1, i, w] & both


@njit(**EXACT)
def lowest_pose(w, straight, crossed):
    """(the pose of the lowest bit set in word w of either, 1 when only the crossed assignment has it)."""
    either = straight | crossed
    low = either & (~either + np.uint64(1))
    bit = np.int64(popcount64(low - np.uint64(1)))
    return w * 64 + bit, 0 if (straight & low) != 0 else 1


@njit(**EXACT)
def _entries(i, j, l, k, swapped):
    """The (arm pair, first site, second site) entries of the link tables a design reads: PSM1's setup joints on
    i and PSM2's on j (swapped: the other way round), PSM3 on l (l < 0: none), the ECM on k."""
    a, b = (j, i) if swapped else (i, j)
    if l < 0:
        return ((0, a, b), (1, a, k), (2, b, k), (0, a, b), (0, a, b), (0, a, b))
    return ((0, a, b), (1, a, k), (2, b, k), (3, a, l), (4, b, l), (5, l, k))


@njit(**EXACT)
def clear_words(t, i, j, l, k, w):
    """Word w of the cart poses at which every arm docks and every pair of arms' links clear (and each arm the
    patient and the table), PSM1 on i and PSM2 on j (straight) or the other way round (crossed)."""
    straight, crossed = docking_words(t.dock, t.dock_camera, i, j, l, k, w)
    for e in _entries(i, j, l, k, False):
        straight &= t.link_words[e[0], e[1], e[2], w]
    for e in _entries(i, j, l, k, True):
        crossed &= t.link_words[e[0], e[1], e[2], w]
    if t.arm_words.shape[0] > 0:  # each arm clear of the patient and the table
        around = t.arm_words[3, k, w] & (t.arm_words[2, l, w] if l >= 0 else ~np.uint64(0))
        straight &= t.arm_words[0, i, w] & t.arm_words[1, j, w] & around
        crossed &= t.arm_words[0, j, w] & t.arm_words[1, i, w] & around
    return straight, crossed


@njit(**EXACT)
def clearest_clear(t, i, j, l, k):
    """Of the cart poses (and ways round) at which every arm docks and every link clears (``clear_words``), the
    one whose least link clearance (``links_at``) is largest: the docking of the most margin (issue 54), not the
    first found (ties: the first, by pose, straight before crossed in each word); (-1, 0) where none clears."""
    best, at, turned = -np.inf, -1, 0
    for w in range(t.dock.shape[2]):
        straight, crossed = clear_words(t, i, j, l, k, w)
        for swapped in range(2):
            word = crossed if swapped else straight
            while word != 0:
                low = word & (~word + np.uint64(1))
                p = w * 64 + np.int64(popcount64(low - np.uint64(1)))
                v, _ = links_at(t, i, j, l, k, p, swapped)
                if at < 0 or v > best:
                    best, at, turned = v, p, swapped
                word &= word - np.uint64(1)
    return at, turned


@njit(**EXACT)
def links_at(t, i, j, l, k, pose, swapped):
    """The least link clearance (m) between the design's arms at a cart pose, and its pair's code (PAIR_CODE * arm pair
    + the tables' link code; NaN and -1 where no entry was computed)."""
    best, code = np.nan, -1
    for e in _entries(i, j, l, k, swapped == 1):
        v = np.float64(t.link_value[e[0], e[1], e[2], pose])
        if v == v and not (best <= v):
            c = np.int64(t.link_code[e[0], e[1], e[2], pose])
            best, code = v, (PAIR_CODE * e[0] + c if c >= 0 else -1)
    if t.arm_words.shape[0] > 0:
        a, b = (j, i) if swapped == 1 else (i, j)
        for arm, site in ((0, a), (1, b), (2, l), (3, k)):
            if site < 0:
                continue
            v = np.float64(t.arm_value[arm, site, pose])
            if v == v and not (best <= v):
                best, code = v, PAIR_CODE * (6 + arm) + np.int64(t.arm_code[arm, site, pose])
    return best, code


@njit(**EXACT)
def clearest_docking(t, i, j, l, k):
    """The cart pose (and way round) at which every arm docks and the least link clearance is largest (the
    first such), for a design whose links clear at none."""
    best, at, turned = -np.inf, -1, 0
    for p in range(t.link_value.shape[3]):
        w, bit = p // 64, np.uint64(1) << np.uint64(p % 64)
        both = (t.dock_camera[k, w] & bit) != 0 and (l < 0 or (t.dock[2, l, w] & bit) != 0)
        if not both:
            continue
        for swapped in range(2):
            a, b = (j, i) if swapped else (i, j)
            if (t.dock[0, a, w] & bit) != 0 and (t.dock[1, b, w] & bit) != 0:
                v, _ = links_at(t, i, j, l, k, p, swapped)
                if at < 0 or v > best:
                    best, at, turned = v, p, swapped
    return at, turned


@njit(**EXACT)
def next_other(x, a, b, c):
    """The first site after ``x`` that is none of a, b and c (n when there is none left: the caller checks)."""
    x += 1
    while x == a or x == b or x == c:
        x += 1
    return x
