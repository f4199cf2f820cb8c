"""What a packing measures, frame by frame, in a periodic box: packing fraction, contacts, rattlers,
pressure and stress. The step leaves its records in State.packing (the contact stages of blobcli/core write them); this
module turns them into the numbers soft-matter codes report (O'Hern et al., PRE 68, 011306 (2003);
Boromand et al., Soft Matter 15, 5854 (2019)).

Stress: the Love–Weber (virial) form over contacts, per blob,
    σ = (1 / A) Σ_blobs Σ_contacts (x - c) ⊗ f,
x a contact's point on the blob, c the blob's centre, f the contact's force on it, A = L_x L_y the box's
area. For a pair, f the force on a, it adds (x - c_a) ⊗ f + (x - c_b) ⊗ (-f) = (c_b - c_a) ⊗ f: the branch
vector times the force, whatever image they meet across, and wherever on the contact the force acts.
The forces are the step's contact impulses over dt, all three kinds the step applies: the pushes
(m Δx / h at the vertex and at the edge point), the velocity-level impulses at the same points, and
the pair's bounce (restitution's uniform Δv, ∓μ Δu n̄, at the midpoint between the centres). All three
are needed: two blobs at rest pressed together are pushed apart by the positions' solve every substep
and held by the bounce rule, and the sum of the two is their true, zero, force. Over a collision the
stress integrates to Σ_steps (c_b - c_a) Δp_a (tests/test_periodic.py: to 0.04%). σ is a Cauchy
stress (N/m in 2D): negative under
compression; the pressure is p = -tr(σ) / 2, positive under compression.

Contact forces: each touching pair's impulses over the step's last substep (all three kinds, as the stress
above) over its length h, F on the pair's first blob; its normal force f = -F · n̂ (n̂ the unit vector from the
first blob's centre to the second's, nearest images), positive when the contact pushes. A blob's net contact force
is the sum of its pairs' F (−F on the second): zero for a blob in mechanical equilibrium without gravity or drive.

Contacts: the blobs each blob touched in the step's last substep (a contact that pushed); a contact carries force
when its f is above BEARING of the mean f of the pushing contacts (a contact whose pushes the velocity stages take
back, at rest, touches and carries nothing). Rattlers: blobs
too loosely held to carry load, removed one after another (their partners lose a contact each) until every
blob left has enough: d + 1 = 3 contacts in 2D without friction (normal forces alone balance only
with three), d = 2 with friction (two contacts balance when the chord between them lies within both
friction cones; the frictional jamming papers count rattlers so, e.g. Papanikolaou, O'Hern & Shattuck,
PRL 110, 198002 (2013)).
"""

from __future__ import annotations

import numpy as np

BEARING = 0.01  # a contact carries force when its normal force is above this fraction of the mean push
RATTLER_BELOW = 3  # contacts: a blob with fewer is a rattler, without friction (2D: d + 1) ...
FRICTIONAL_RATTLER_BELOW = 2  # ... and with (d)


def contact_counts(touching: np.ndarray, blobs: int) -> np.ndarray:
    """(B,) int32: how many blobs each blob touches, from the touching pairs (P, 2)."""
    return np.bincount(touching.ravel(), minlength=blobs).astype(np.int32)


def rattler_below(material: np.ndarray) -> int:
    """The contacts a blob needs not to be a rattler, from the blobs' material (B, 3): frictional when any
    blob has a static friction coefficient."""
    return FRICTIONAL_RATTLER_BELOW if np.any(material[:, 0] > 0.0) else RATTLER_BELOW


def rattlers(touching: np.ndarray, blobs: int, below: int = RATTLER_BELOW) -> np.ndarray:
    """(B,) bool: the rattlers, removed repeatedly until every blob left has `below` contacts."""
    gone = np.zeros(blobs, bool)
    while True:
        live = touching[~(gone[touching[:, 0]] | gone[touching[:, 1]])]
        count = np.bincount(live.ravel(), minlength=blobs)
        new = ~gone & (count < below)
        if not new.any():
            return gone
        gone |= new


def mean_contacts(touching: np.ndarray, rattler: np.ndarray) -> tuple[float, float]:
    """(z with every blob, z without the rattlers): 2 × contacts / blobs."""
    blobs = len(rattler)
    kept = touching[~(rattler[touching[:, 0]] | rattler[touching[:, 1]])]
    left = int((~rattler).sum())
    return 2.0 * len(touching) / blobs, (2.0 * len(kept) / left if left else 0.0)


def rigid(touching: np.ndarray, rattler: np.ndarray, below: int) -> bool:
    """Whether the blobs left after the rattlers have the contacts to be rigid in a periodic box: a
    frictionless backbone of N' blobs needs N_c >= d (N' - 1) + 1 = 2 N' - 1 (d N' degrees of freedom less the
    d translations, and one more for a positive pressure: Goodrich, Liu & Nagel, PRL 109, 095704 (2012)); a
    frictional one, two constraints per contact on d + 1 = 3 degrees of freedom a blob, N_c >= (3 N' - 2) / 2.
    (`below`: rattler_below, which says which.)"""
    left = int((~rattler).sum())
    if left == 0:
        return False
    kept = int((~(rattler[touching[:, 0]] | rattler[touching[:, 1]])).sum())
    return kept >= (2 * left - 1 if below == RATTLER_BELOW else (3 * left - 2) / 2)


def stress(virial: np.ndarray, dt: float, box) -> np.ndarray:
    """(2, 2) N/m: σ = Σ_blobs (x - c) ⊗ J / (dt A), from the step's virial records (B, 4)."""
    return virial.sum(axis=0).reshape(2, 2) / (dt * box[0] * box[1])


def pressure(sigma: np.ndarray) -> float:
    """p = -tr(σ) / 2 (N/m), positive under compression."""
    return -0.5 * float(sigma[0, 0] + sigma[1, 1])


def packing_fraction(area: np.ndarray, box) -> float:
    """The blobs' area over the box's."""
    return float(np.abs(area).sum() / (box[0] * box[1]))


def centres(position: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(B, 2) m: each blob's vertex average, from the positions (N, 2)."""
    return np.add.reduceat(position, offsets[:-1]) / np.diff(offsets)[:, None]


def normal_forces(touching: np.ndarray, force: np.ndarray, centre: np.ndarray, box, tilt: float = 0.0) -> np.ndarray:
    """(P,) N: each touching pair's normal force f = -F · n̂, positive when it pushes (module docstring), n̂ along
    the nearest image of the branch vector in the box (L_x, L_y), its rows sheared by `tilt` = γ L_y."""
    d = centre[touching[:, 1]] - centre[touching[:, 0]]
    rows = np.round(d[:, 1] / box[1])
    d[:, 0] -= rows * tilt
    d[:, 1] -= rows * box[1]
    d[:, 0] -= box[0] * np.round(d[:, 0] / box[0])
    return -(force * d).sum(axis=1) / np.hypot(d[:, 0], d[:, 1])


def net_forces(touching: np.ndarray, force: np.ndarray, blobs: int) -> np.ndarray:
    """(B, 2) N: each blob's net contact force, Σ over its pairs of ±F."""
    net = np.zeros((blobs, 2))
    np.add.at(net, touching[:, 0], force)
    np.add.at(net, touching[:, 1], -force)
    return net


def bearing(normal: np.ndarray) -> np.ndarray:
    """(P,) bool: the contacts that carry force, f > BEARING × the mean push (none when nothing pushes)."""
    pushing = normal > 0.0
    return normal > BEARING * normal[pushing].mean() if pushing.any() else np.zeros(len(normal), bool)
