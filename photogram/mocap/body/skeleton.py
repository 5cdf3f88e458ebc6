"""Skeletons: joint names, limbs, left/right pairs and mappings between them.

The reconstruction skeleton of the alpine-skiing paper (Bachmann et al.,
"Motion Capture from Pan-Tilt Cameras with Unknown Orientation") has 24
joints, :data:`SKI24`::

     0 head          1 neck
     2 r_shoulder    3 r_elbow    4 r_hand     5 r_pole       (pole basket)
     6 l_shoulder    7 l_elbow    8 l_hand     9 l_pole
    10 r_hip        11 r_knee    12 r_ankle
    13 l_hip        14 l_knee    15 l_ankle
    16 r_ski_tip    17 r_toes    18 r_heel    19 r_ski_tail
    20 l_ski_tip    21 l_toes    22 l_heel    23 l_ski_tail

Assumed definitions (the paper's figures are not available here): ``head``
is the top of the head (vertex), ``neck`` the upper neck (as OpenPose
BODY_25B's HeadTop/UpperNeck), ``hand`` the wrist joint centre, ``pole`` the
centre of the pole basket, ``toes``/``heel`` the front and back of the ski
boot on the ski, ``ski_tip``/``ski_tail`` the ends of the ski. The first 14
joints (head ... l_ankle without the pole baskets) are the *body joints*
(:data:`BODY14`) of the body-only metrics.

Detector skeletons (OpenPose BODY_25B and BODY_25, COCO-17, mediapipe's 33
landmarks) are either reconstructed as generic skeletons (their own joints
and limbs) or mapped onto SKI24 with :func:`map_joints`; a mapped joint may
be the mean of several source joints (its confidence is then the minimum).
Joints a detector does not have (skis, poles) stay unobserved.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from photogram.errors import InputError

__all__ = ["Skeleton", "SKI24", "BODY25B", "BODY25", "COCO17", "MEDIAPIPE33", "SKELETONS",
           "BODY14", "get_skeleton", "mapping_to", "map_joints"]


@dataclass(frozen=True)
class Skeleton:
    """A named set of joints with limbs (pairs of joint names).

    ``pairs`` are left/right joint pairs (for swaps); ``mappings`` maps the
    name of another skeleton to ``{target joint: (source joints...)}`` that
    says how that skeleton's joints give this skeleton's joints.
    """

    name: str
    joints: tuple[str, ...]
    limbs: tuple[tuple[str, str], ...]
    pairs: tuple[tuple[str, str], ...] = ()
    description: str = ""
    mappings: dict = field(default_factory=dict, compare=False, hash=False)

    @property
    def n_joints(self) -> int:
        return len(self.joints)

    def index(self, name: str) -> int:
        try:
            return self.joints.index(name)
        except ValueError:
            raise InputError(f"skeleton {self.name} has no joint {name!r}",
                             hint="its joints: " + ", ".join(self.joints)) from None

    def indices(self, names) -> np.ndarray:
        return np.array([self.index(n) for n in names], dtype=int)

    def limb_indices(self) -> np.ndarray:
        """(n_limbs, 2) joint indices of the limbs."""
        return np.array([[self.index(a), self.index(b)] for a, b in self.limbs],
                        dtype=int).reshape(-1, 2)

    def swap_permutation(self) -> np.ndarray:
        """Index array that exchanges every left/right pair."""
        perm = np.arange(self.n_joints)
        for a, b in self.pairs:
            i, j = self.index(a), self.index(b)
            perm[i], perm[j] = j, i
        return perm

    def has(self, *names: str) -> bool:
        return all(n in self.joints for n in names)


def _sided(prefix_r: str, prefix_l: str, names) -> tuple[tuple[str, str], ...]:
    return tuple((prefix_r + n, prefix_l + n) for n in names)


# --------------------------------------------------------------------------
# the ski skeleton
# --------------------------------------------------------------------------
_SKI_JOINTS = ("head", "neck",
               "r_shoulder", "r_elbow", "r_hand", "r_pole",
               "l_shoulder", "l_elbow", "l_hand", "l_pole",
               "r_hip", "r_knee", "r_ankle",
               "l_hip", "l_knee", "l_ankle",
               "r_ski_tip", "r_toes", "r_heel", "r_ski_tail",
               "l_ski_tip", "l_toes", "l_heel", "l_ski_tail")


def _ski_limbs():
    limbs = [("head", "neck")]
    for s in ("r_", "l_"):
        limbs += [("neck", s + "shoulder"), (s + "shoulder", s + "elbow"),
                  (s + "elbow", s + "hand"), (s + "hand", s + "pole"),
                  (s + "shoulder", s + "hip"), (s + "hip", s + "knee"),
                  (s + "knee", s + "ankle"), (s + "ankle", s + "toes"),
                  (s + "ankle", s + "heel"), (s + "ski_tip", s + "toes"),
                  (s + "toes", s + "heel"), (s + "heel", s + "ski_tail")]
    limbs += [("r_hip", "l_hip"), ("r_shoulder", "l_shoulder")]
    return tuple(limbs)


# BODY_25B (OpenPose experimental model, used by Pose2Sim)
_B25B = ("Nose", "LEye", "REye", "LEar", "REar", "LShoulder", "RShoulder", "LElbow",
         "RElbow", "LWrist", "RWrist", "LHip", "RHip", "LKnee", "RKnee", "LAnkle", "RAnkle",
         "Neck", "Head", "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel")
# BODY_25 (OpenPose default): Neck is the lower neck (between the shoulders)
_B25 = ("Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist",
        "MidHip", "RHip", "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye",
        "REar", "LEar", "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel")
_COCO = ("nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder",
         "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
         "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle")
_MP = ("nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner",
       "right_eye", "right_eye_outer", "left_ear", "right_ear", "mouth_left", "mouth_right",
       "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist",
       "right_wrist", "left_pinky", "right_pinky", "left_index", "right_index",
       "left_thumb", "right_thumb", "left_hip", "right_hip", "left_knee", "right_knee",
       "left_ankle", "right_ankle", "left_heel", "right_heel", "left_foot_index",
       "right_foot_index")


def _openpose_limbs(neck_head: bool):
    limbs = []
    for s in "RL":
        limbs += [(s + "Hip", s + "Knee"), (s + "Knee", s + "Ankle"),
                  (s + "Ankle", s + "BigToe"), (s + "BigToe", s + "SmallToe"),
                  (s + "Ankle", s + "Heel"), (s + "Shoulder", s + "Elbow"),
                  (s + "Elbow", s + "Wrist"), ("Neck", s + "Shoulder")]
    limbs += [("RHip", "LHip")]
    if neck_head:      # Pose2Sim's BODY_25B tree: Neck - Head - Nose
        limbs += [("Neck", "Head"), ("Head", "Nose")]
    else:
        limbs += [("Neck", "Nose"), ("Neck", "MidHip"), ("MidHip", "RHip"), ("MidHip", "LHip")]
    return tuple(limbs)


def _names_limbs(names, sides):
    limbs = []
    for s in sides:
        limbs += [(f"{s}_shoulder", f"{s}_elbow"), (f"{s}_elbow", f"{s}_wrist"),
                  (f"{s}_hip", f"{s}_knee"), (f"{s}_knee", f"{s}_ankle"),
                  (f"{s}_shoulder", f"{s}_hip")]
    limbs += [("left_shoulder", "right_shoulder"), ("left_hip", "right_hip")]
    return tuple(limbs)


def _mid(*names):
    return tuple(names)


SKI24 = Skeleton(
    "ski24", _SKI_JOINTS, _ski_limbs(),
    pairs=_sided("r_", "l_", ("shoulder", "elbow", "hand", "pole", "hip", "knee", "ankle",
                              "ski_tip", "toes", "heel", "ski_tail")),
    description="alpine-skiing skeleton: 14 body joints, pole baskets, 4 points per ski",
    mappings={
        "body25b": {"head": ("Head",), "neck": ("Neck",),
                    **{f"{s}_{j}": (f"{S}{J}",) for s, S in (("r", "R"), ("l", "L"))
                       for j, J in (("shoulder", "Shoulder"), ("elbow", "Elbow"),
                                    ("hand", "Wrist"), ("hip", "Hip"), ("knee", "Knee"),
                                    ("ankle", "Ankle"), ("toes", "BigToe"), ("heel", "Heel"))}},
        # BODY_25 has no head top: the head is approximated by the mean of the
        # ears (the head centre), the neck by its Neck (between the shoulders)
        "body25": {"head": _mid("REar", "LEar"), "neck": ("Neck",),
                   **{f"{s}_{j}": (f"{S}{J}",) for s, S in (("r", "R"), ("l", "L"))
                      for j, J in (("shoulder", "Shoulder"), ("elbow", "Elbow"),
                                   ("hand", "Wrist"), ("hip", "Hip"), ("knee", "Knee"),
                                   ("ankle", "Ankle"), ("toes", "BigToe"), ("heel", "Heel"))}},
        "coco17": {"head": _mid("right_ear", "left_ear"),
                   "neck": _mid("right_shoulder", "left_shoulder"),
                   **{f"{s}_{j}": (f"{S}_{J}",) for s, S in (("r", "right"), ("l", "left"))
                      for j, J in (("shoulder", "shoulder"), ("elbow", "elbow"),
                                   ("hand", "wrist"), ("hip", "hip"), ("knee", "knee"),
                                   ("ankle", "ankle"))}},
        "mediapipe33": {"head": _mid("right_ear", "left_ear"),
                        "neck": _mid("right_shoulder", "left_shoulder"),
                        **{f"{s}_{j}": (f"{S}_{J}",) for s, S in (("r", "right"), ("l", "left"))
                           for j, J in (("shoulder", "shoulder"), ("elbow", "elbow"),
                                        ("hand", "wrist"), ("hip", "hip"), ("knee", "knee"),
                                        ("ankle", "ankle"), ("toes", "foot_index"),
                                        ("heel", "heel"))}},
    })

BODY25B = Skeleton("body25b", _B25B, _openpose_limbs(True),
                   pairs=tuple(("R" + n, "L" + n) for n in (
                       "Eye", "Ear", "Shoulder", "Elbow", "Wrist", "Hip", "Knee", "Ankle",
                       "BigToe", "SmallToe", "Heel")),
                   description="OpenPose BODY_25B (Pose2Sim's default; Neck = upper neck, "
                               "Head = head top)")
BODY25 = Skeleton("body25", _B25, _openpose_limbs(False),
                  pairs=tuple(("R" + n, "L" + n) for n in (
                      "Eye", "Ear", "Shoulder", "Elbow", "Wrist", "Hip", "Knee", "Ankle",
                      "BigToe", "SmallToe", "Heel")),
                  description="OpenPose BODY_25")
COCO17 = Skeleton("coco17", _COCO, _names_limbs(_COCO, ("left", "right")),
                  pairs=tuple(("right_" + n, "left_" + n) for n in (
                      "eye", "ear", "shoulder", "elbow", "wrist", "hip", "knee", "ankle")),
                  description="COCO 17 keypoints")
MEDIAPIPE33 = Skeleton("mediapipe33", _MP, _names_limbs(_MP, ("left", "right")) + (
    ("left_ankle", "left_heel"), ("left_ankle", "left_foot_index"),
    ("right_ankle", "right_heel"), ("right_ankle", "right_foot_index")),
    pairs=tuple(("right_" + n, "left_" + n) for n in (
        "eye_inner", "eye", "eye_outer", "ear", "shoulder", "elbow", "wrist", "pinky",
        "index", "thumb", "hip", "knee", "ankle", "heel", "foot_index")) + (
        ("mouth_right", "mouth_left"),),
    description="mediapipe pose (BlazePose) 33 landmarks")

SKELETONS: dict[str, Skeleton] = {s.name: s for s in (SKI24, BODY25B, BODY25, COCO17,
                                                       MEDIAPIPE33)}

#: the 14 body joints of the body-only metrics
BODY14 = ("head", "neck", "r_shoulder", "r_elbow", "r_hand", "l_shoulder", "l_elbow",
          "l_hand", "r_hip", "r_knee", "r_ankle", "l_hip", "l_knee", "l_ankle")


def get_skeleton(name: str) -> Skeleton:
    """The skeleton called ``name`` (InputError listing the known ones)."""
    try:
        return SKELETONS[str(name).lower()]
    except KeyError:
        raise InputError(f"unknown skeleton {name!r}",
                         hint="known skeletons: " + ", ".join(SKELETONS)) from None


def mapping_to(target: Skeleton, source: Skeleton) -> dict[str, tuple[str, ...]]:
    """``{target joint: source joints}`` for mapping ``source`` onto ``target``
    (identity if they are the same skeleton)."""
    if target.name == source.name:
        return {j: (j,) for j in target.joints}
    if source.name not in target.mappings:
        raise InputError(f"no mapping from skeleton {source.name} to {target.name}",
                         hint=f"reconstruct with skeleton = \"{source.name}\" (generic) or "
                              f"use one of: {', '.join(target.mappings) or 'none'}")
    return target.mappings[source.name]


def map_joints(joints: np.ndarray, source: Skeleton, target: Skeleton) -> np.ndarray:
    """Map detections (..., J_source, 3) (x, y, confidence) onto ``target``.

    A target joint given by several source joints is their mean, with the
    minimum confidence (0 if any is missing); unmapped target joints get NaN
    coordinates and confidence 0.
    """
    joints = np.asarray(joints, dtype=float)
    if joints.shape[-2] != source.n_joints:
        raise InputError(f"detections have {joints.shape[-2]} joints, skeleton "
                         f"{source.name} has {source.n_joints}")
    mapping = mapping_to(target, source)
    out = np.full(joints.shape[:-2] + (target.n_joints, joints.shape[-1]), np.nan)
    out[..., 2] = 0.0
    for name, srcs in mapping.items():
        idx = source.indices(srcs)
        sub = joints[..., idx, :]
        conf = sub[..., 2].min(axis=-1)
        xy = sub[..., :2].mean(axis=-2)
        ok = conf > 0
        t = target.index(name)
        out[..., t, :2] = np.where(ok[..., None], xy, np.nan)
        out[..., t, 2] = np.where(ok, conf, 0.0)
    return out
