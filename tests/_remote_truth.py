"""What the remote-interface tests compare against: tolerances and the study's inputs."""

from __future__ import annotations

#: Tolerances, by what is compared.
TOL = {
    "same_numbers": 1e-12,  # the server and this process compute the same floats
    "orientation": 1e-9,  # the reached orientation against the asked one
    "angles_deg": 1e-9,  # angles sent and read back [deg]
}
#: The published study's input with a link collision [deg] and its colliding pairs.
STUDY_COLLISION_DEG = [60.0, 90.0, 220.0]
STUDY_COLLISION_PAIRS = {
    ("proximal_2", "proximal_3"),
    ("proximal_2", "distal_3"),
    ("proximal_3", "distal_2"),
    ("distal_2", "distal_3"),
}
#: The published study's input, safe [deg].
SAFE_DEG = [60.0, 90.0, 120.0]
