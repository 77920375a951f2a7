"""The calibrated confidence: the probability that a registration's pose is right.

*Right* means within 5 degrees and 1 cm of the truth at the source's centroid, the
errors taken over the object's symmetries where it has some (a can turned about its
axis is right). The probability is a logistic model of the pose's evidence
(:class:`o3d_spectral.evidence.pose.PoseEvidence`)::

    confidence = 1 / (1 + exp(-z)),   z = BIAS + sum(COEFFICIENTS[name] * feature[name])

with the features of :func:`features`; a pose that no point corroborates (a fit of 0:
none of the source's points the target could show lies within a voxel of it) has
confidence 0, whatever the rest of its evidence. A warning says the pose may be wrong
when the confidence is under :data:`WARN_BELOW`.

The coefficients were fitted by ``python eval/calibrate_confidence.py --out
out/calibrate_confidence`` (L2-penalised logistic regression on standardised features,
then written back in raw units) on the fitting part of its development groups (model
views, occlusions and scenes, crops of models, turntable pairs, the real dragon scan
pairs and YCB-Video crops, a crop of an object against its scene, wrong-object pairs),
and checked on the held-back part; ``docs/errors.md`` gives the held-back figures and
``docs/data/`` the script's output (``calibrate_confidence_*``).
"""

from __future__ import annotations

import numpy as np

from .constants import BIAS, COEFFICIENTS, PLANE_FLOOR, SHARE_CLIP, WARN_BELOW
from .pose import PoseEvidence
from .verification import ASYMMETRIC

__all__ = ["BIAS", "COEFFICIENTS", "FEATURES", "WARN_BELOW", "features", "confidence",
           "probability"]


#: The model's features, in the order of :data:`COEFFICIENTS`.
FEATURES = ("logit_fit_object", "logit_fit_views", "two_views", "logit_target_fit",
            "log_plane_object", "log_plane_views", "logit_normals_object", "sqrt_free_space",
            "sensor_known", "ambiguous_different", "support_gap")


def _logit(share: float) -> float:
    p = min(max(float(share), SHARE_CLIP), 1.0 - SHARE_CLIP)
    return float(np.log(p / (1.0 - p)))


def features(evidence: PoseEvidence) -> dict[str, float]:
    """The model's features of ``evidence`` (see :data:`FEATURES`).

    - ``logit_fit_object`` / ``logit_fit_views``: the logit of the fit, apart for two
      views matched whole (their fit is their overlap) and for the rest, with
      ``two_views`` (0 or 1) their own intercept;
    - ``log_plane_object`` / ``log_plane_views``: the logarithm of the plane distance,
      apart in the same way;
    - ``logit_normals_object``: the logit of the normals' agreement, for the rest only
      (between two views a surface seen at grazing angles by one has poor normals);
    - ``logit_target_fit``: the logit of the target fit;
    - ``sqrt_free_space`` and ``sensor_known``: 0 where the target's sensor is unknown
      (``evidence.free_space`` None), the model then resting on the other features;
    - ``support_gap``: the logit of the motion support less the logit of the fit: near
      0 where the inliers resist every motion as much as the fit says they should, very
      negative where a motion is resisted by the points that miss only (a mug's body
      matched, its handle not);
    - ``ambiguous_different``: 1 where a distinct pose fits as well and is not the
      returned one turned by a symmetry of the source (one of the two is wrong, and the
      target cannot tell which).
    """
    free = evidence.free_space
    fit = _logit(evidence.fit)
    plane = float(np.log(evidence.plane_distance + PLANE_FLOOR))
    views = evidence.two_views
    different = evidence.ambiguous and evidence.rival_self_match >= ASYMMETRIC
    return {
        "logit_fit_object": 0.0 if views else fit,
        "logit_fit_views": fit if views else 0.0,
        "two_views": float(views),
        "logit_target_fit": _logit(evidence.target_fit),
        "log_plane_object": 0.0 if views else plane,
        "log_plane_views": plane if views else 0.0,
        "logit_normals_object": 0.0 if views else _logit(evidence.normal_agreement),
        "sqrt_free_space": 0.0 if free is None else float(np.sqrt(free)),
        "sensor_known": 0.0 if free is None else 1.0,
        "ambiguous_different": float(different),
        "support_gap": _logit(evidence.motion_support) - fit,
    }


def probability(values: dict[str, float], bias: float = BIAS,
                coefficients: dict[str, float] | None = None) -> float:
    """The logistic model at the features ``values`` (:func:`features`), in [0, 1]."""
    coefficients = COEFFICIENTS if coefficients is None else coefficients
    z = bias + sum(coefficients[name] * values[name] for name in FEATURES)
    return float(1.0 / (1.0 + np.exp(-np.clip(z, -500.0, 500.0))))


def confidence(evidence: PoseEvidence) -> float:
    """The probability, in [0, 1], that the pose measured by ``evidence`` is right; 0
    where no point corroborates it (``evidence.fit`` 0: between two views the model reads
    a small fit as a small overlap, and was fitted on none this small)."""
    if evidence.fit <= 0.0:
        return 0.0
    return probability(features(evidence))
