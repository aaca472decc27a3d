"""The 3D scene of a run's MCAP log (``foxglove.SceneUpdate`` on ``/scene``).

Each frame's update first deletes every entity, then draws, each in its own frame of
``/tf`` (so the 3D panel places it with that frame's transform):

* ``deck`` (frame ``deck``): the deck plate, the beacon ring and the beacons (the bow's in
  its layout colour, red by default; beacons are drawn at a tenth of the ring radius, since
  their true size, a few decimetres, is invisible from the camera's height);
* ``camera`` (frame ``camera``, OpenCV axes): the camera's frustum, from the optical centre
  to the image corners at the camera's height;
* ``deck_est/<detector>--<method>`` (frame of the same name): each estimator's deck as a
  translucent disc of the ring's radius, for the frames that estimator solved.
"""

from __future__ import annotations

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.CylinderPrimitive_pb2 import CylinderPrimitive
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneEntityDeletion_pb2 import SceneEntityDeletion
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.SpherePrimitive_pb2 import SpherePrimitive
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.timestamp_pb2 import Timestamp

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout

__all__ = ["DECK_RGBA", "ESTIMATE_RGBA", "FRUSTUM_RGBA", "RING_RGBA", "camera_entity", "deck_entity",
           "estimate_entity", "scene_update"]

RGBA = tuple[float, float, float, float]

DECK_RGBA: RGBA = (0.42, 0.43, 0.45, 1.0)
RING_RGBA: RGBA = (0.95, 0.78, 0.16, 1.0)
FRUSTUM_RGBA: RGBA = (0.3, 0.8, 1.0, 1.0)
#: Translucent colours of the estimators' decks, in the order of the run's estimate pairs.
ESTIMATE_RGBA: tuple[RGBA, ...] = ((0.2, 0.6, 1.0, 0.35), (1.0, 0.4, 0.9, 0.35), (0.3, 1.0, 0.5, 0.35),
                                   (1.0, 0.6, 0.1, 0.35), (0.7, 0.5, 1.0, 0.35), (0.1, 0.9, 0.9, 0.35))
_PLATE_THICKNESS_M = 0.2
_RING_POINTS = 96


def _ts(stamp_ns: int) -> Timestamp:
    return Timestamp(seconds=stamp_ns // 1_000_000_000, nanos=stamp_ns % 1_000_000_000)


def _color(rgba: RGBA) -> Color:
    return Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])


def _pose(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Pose:
    return Pose(position=Vector3(x=x, y=y, z=z), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))


def _entity(entity_id: str, frame_id: str, stamp_ns: int) -> SceneEntity:
    return SceneEntity(timestamp=_ts(stamp_ns), frame_id=frame_id, id=entity_id, frame_locked=True)


def deck_entity(layout: DeckLayout, deck_half_size_m: float, stamp_ns: int) -> SceneEntity:
    """The deck plate, ring and beacons in frame ``deck`` (x bow, y port, z up).

    Parameters
    ----------
    layout : DeckLayout
        Beacon positions and colours.
    deck_half_size_m : float
        Half the side of the square deck plate, metres.
    stamp_ns : int
        Timestamp, integer nanoseconds (the frame's log time).
    """
    e = _entity("deck", "deck", stamp_ns)
    side = 2.0 * deck_half_size_m
    e.cubes.append(CubePrimitive(pose=_pose(z=-_PLATE_THICKNESS_M / 2 - 0.02),
                                 size=Vector3(x=side, y=side, z=_PLATE_THICKNESS_M), color=_color(DECK_RGBA)))
    ang = 2.0 * np.pi * np.arange(_RING_POINTS) / _RING_POINTS
    r = layout.radius_m
    e.lines.append(LinePrimitive(type=LinePrimitive.Type.LINE_LOOP, pose=_pose(), thickness=3.0, scale_invariant=True,
                                 points=[Point3(x=float(r * np.cos(a)), y=float(r * np.sin(a)), z=0.02) for a in ang],
                                 color=_color(RING_RGBA)))
    d = 0.1 * r
    for i, p in enumerate(layout.positions_deck_m()):
        rgb = layout.bow_rgb if i == layout.bow_id else layout.beacon_rgb
        e.spheres.append(SpherePrimitive(pose=_pose(float(p[0]), float(p[1]), float(p[2]) + d / 2),
                                         size=Vector3(x=d, y=d, z=d), color=_color((*rgb, 1.0))))
    return e


def camera_entity(camera: CameraModel, depth_m: float, stamp_ns: int) -> SceneEntity:
    """The camera's frustum in frame ``camera`` (OpenCV axes: x right, y down, z forward).

    Parameters
    ----------
    camera : CameraModel
        Its ``K`` and size give the rays through the image corners (pixel-corner edges).
    depth_m : float
        Distance of the frustum's base along the optical axis, metres.
    stamp_ns : int
        Timestamp, integer nanoseconds.
    """
    e = _entity("camera", "camera", stamp_ns)
    uv = np.array([[-0.5, -0.5], [camera.width_px - 0.5, -0.5], [camera.width_px - 0.5, camera.height_px - 0.5],
                   [-0.5, camera.height_px - 0.5]])
    rays = np.column_stack([(uv[:, 0] - camera.cx) / camera.fx, (uv[:, 1] - camera.cy) / camera.fy, np.ones(4)])
    corners = [Point3(x=float(x), y=float(y), z=float(z)) for x, y, z in rays * depth_m]
    apex = Point3(x=0.0, y=0.0, z=0.0)
    pts = []
    for k in range(4):
        pts += [apex, corners[k], corners[k], corners[(k + 1) % 4]]
    e.lines.append(LinePrimitive(type=LinePrimitive.Type.LINE_LIST, pose=_pose(), thickness=2.0, scale_invariant=True,
                                 points=pts, color=_color(FRUSTUM_RGBA)))
    return e


def estimate_entity(frame_id: str, radius_m: float, rgba: RGBA, stamp_ns: int) -> SceneEntity:
    """An estimated deck: a translucent disc of ``radius_m`` in ``frame_id`` (its estimate's frame)."""
    e = _entity(frame_id, frame_id, stamp_ns)
    e.cylinders.append(CylinderPrimitive(pose=_pose(z=0.05), size=Vector3(x=2 * radius_m, y=2 * radius_m, z=0.1),
                                         bottom_scale=1.0, top_scale=1.0, color=_color(rgba)))
    return e


def scene_update(entities: list[SceneEntity], stamp_ns: int) -> SceneUpdate:
    """A frame's scene: delete every earlier entity, then draw ``entities``."""
    return SceneUpdate(deletions=[SceneEntityDeletion(timestamp=_ts(stamp_ns), type=SceneEntityDeletion.Type.ALL)],
                       entities=entities)
