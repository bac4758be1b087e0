"""Visibility culling keeps the wall a camera sees and drops what lies behind it or in the free space before it."""
import numpy as np
import trimesh

from nicer_stream.mesh.visibility import DepthView, cull_by_rendered_depth, seen_through_vertices, visible_vertices
from nicer_stream.types import Intrinsics

INTR = Intrinsics(50.0, 50.0, 31.5, 23.5, 64, 48)


def _wall(z: float) -> trimesh.Trimesh:
    return trimesh.Trimesh(vertices=[[-0.5, -0.5, z], [0.5, -0.5, z], [0.5, 0.5, z], [-0.5, 0.5, z]], faces=[[0, 1, 2], [0, 2, 3]])


def test_front_wall_kept_hidden_wall_dropped():
    view = DepthView(np.eye(4), INTR, np.full((48, 64), 2.0))
    both = trimesh.util.concatenate([_wall(2.0), _wall(4.0)])
    out = cull_by_rendered_depth(both, [view], margin=0.1)
    assert np.allclose(out.vertices[:, 2], 2.0)
    assert len(out.faces) == 2


def test_points_outside_the_image_or_behind_are_not_visible():
    view = DepthView(np.eye(4), INTR, np.full((48, 64), 5.0))
    pts = np.array([[0, 0, 1.0], [0, 0, -1.0], [10, 0, 1.0], [0, 0, 5.05], [0, 0, 5.5]])
    assert visible_vertices(pts, [view], margin=0.1).tolist() == [True, False, False, True, False]


def test_a_floater_the_render_sees_through_is_dropped_unless_another_view_sees_it_there():
    wall, floater = _wall(2.0), _wall(1.0)
    view = DepthView(np.eye(4), INTR, np.full((48, 64), 2.0))  # this render's rays reach the wall at 2 m
    out = cull_by_rendered_depth(trimesh.util.concatenate([wall, floater]), [view], margin=0.1)
    assert np.allclose(out.vertices[:, 2], 2.0) and len(out.faces) == 2
    pts = np.array([[0, 0, 1.0], [0, 0, 1.95], [0, 0, 2.0], [0, 0, 3.0]])
    assert seen_through_vertices(pts, [view], margin=0.1).tolist() == [True, False, False, False]
    # A face is dropped only when all its vertices are seen through: one vertex on the wall keeps it.
    tri = trimesh.Trimesh(vertices=[[0, 0, 2.0], [0.1, 0, 1.0], [0, 0.1, 1.0]], faces=[[0, 1, 2]])
    assert len(cull_by_rendered_depth(tri, [view], margin=0.1).faces) == 1


def test_a_measured_depth_culls_what_lies_in_front_of_it_by_more_than_its_fraction():
    render = DepthView(np.eye(4), INTR, np.full((48, 64), 1.5))  # the map renders the halo at 1.5 m
    measured = np.full((48, 64), 2.0)  # the stereo saw the wall at 2 m through it
    measured[:, :32] = 0.0  # and nothing on the left half
    stereo = DepthView(np.eye(4), INTR, measured)
    pts = np.array([[0.2, 0, 1.5], [0.2, 0, 1.95], [0.2, 0, 2.0], [-0.2, 0, 1.5]])
    assert seen_through_vertices(pts, [stereo], 0.0, rel=0.05).tolist() == [True, False, False, False]
    right = trimesh.Trimesh(vertices=[[0.1, -0.1, 1.5], [0.3, -0.1, 1.5], [0.3, 0.1, 1.5]], faces=[[0, 1, 2]])
    left = trimesh.Trimesh(vertices=[[-0.3, -0.1, 1.5], [-0.1, -0.1, 1.5], [-0.1, 0.1, 1.5]], faces=[[0, 1, 2]])
    both = trimesh.util.concatenate([right, left])
    assert len(cull_by_rendered_depth(both, [render], margin=0.1).faces) == 2  # the render agrees with both
    out = cull_by_rendered_depth(both, [render], margin=0.1, measured=[stereo], measured_rel=0.05)
    assert len(out.faces) == 1 and (out.vertices[:, 0] < 0).all()  # unknown depth culls nothing
    # Within the fraction (1.92 m against 2 m at 5%) a surface is kept.
    near = trimesh.Trimesh(vertices=right.vertices * [1, 1, 1.92 / 1.5], faces=right.faces)
    assert len(cull_by_rendered_depth(near, [render], margin=0.5, measured=[stereo], measured_rel=0.05).faces) == 1
