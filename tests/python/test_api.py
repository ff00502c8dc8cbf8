"""The slamvdb Python API: build a map from numpy arrays, query it, save and load it."""
import json
import math

import numpy as np
import pytest

import slamvdb


def ground_and_wall():
    """World points of a ground plane (z = 0) and a wall (y = 4), every 0.2 m."""
    pts = [(x, y, 0.01) for x in np.arange(-8, 8, 0.2) for y in np.arange(-4, 4, 0.2)]
    pts += [(x, 4.01, z) for x in np.arange(-8, 8, 0.2) for z in np.arange(0.2, 3, 0.2)]
    return np.array(pts, dtype=np.float32)


def pose(x):
    T = np.eye(4)
    T[0, 3], T[2, 3] = x, 1.5
    return T


def build(tmp_path, features=None):
    """A small map: two scans, and a feature map (by default one that says class 3 everywhere)."""
    m = slamvdb.Map(voxel_size=0.25, dim=16, precision="fp16", submap_length=0, model_id="test-space")
    world = ground_and_wall()
    for i, x in enumerate([0.0, 0.5]):
        T = pose(x)
        sensor = (np.linalg.inv(T) @ np.c_[world, np.ones(len(world))].T).T[:, :3]
        stats = m.integrate_scan(float(i), sensor.astype(np.float32), T)
        assert stats["points"] == len(world)
    # A camera at x = -6 looking along +x (camera z forward, x right = -y world, y down = -z world).
    T_world_camera = np.eye(4)
    T_world_camera[:3, :3] = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], dtype=float)
    T_world_camera[:3, 3] = [-6.0, 0.0, 1.5]
    if features is None:
        features = np.zeros((48, 64, 16), dtype=np.float32)
        features[:, :, 3] = 1.0  # every pixel looks like class 3
    fused = m.fuse_features(1.0, features, {"fx": 40.0, "fy": 40.0, "cx": 31.5, "cy": 23.5}, T_world_camera)
    assert fused["fused"] and fused["voxels"] > 50
    assert fused["feature_precision"] == ("fp16" if features.dtype == np.float16 else "fp32")
    m.finish()
    return m


def test_build_query_save_load(tmp_path):
    m = build(tmp_path)
    positions, embeddings, counts = m.semantic_voxels()
    assert positions.shape[1] == 3 and embeddings.shape == (len(positions), 16)
    assert (counts >= 1).all()
    assert np.allclose(embeddings[:, 3], 1.0, atol=1e-3)
    occupied = m.occupied_voxels()
    assert len(occupied) > len(positions)  # the camera sees only part of what the LiDAR does

    q = np.zeros(16, dtype=np.float32)
    q[3] = 1.0
    pos, scores, cnt = m.search(q, top_k=10)
    assert len(pos) == 10 and scores[0] == pytest.approx(1.0, abs=1e-3)
    assert list(scores) == sorted(scores, reverse=True)

    answer = m.at(np.vstack([positions[:1], [[100.0, 100.0, 100.0]]]))
    assert list(answer["found"]) == [True, False]
    assert answer["counts"][0] == counts[0]
    # Observation statistics: the paper's rule weighs each view 1; identical views do not spread.
    weights, spreads = m.statistics()
    assert weights.shape == counts.shape and np.array_equal(weights, counts.astype(np.float32))
    assert np.allclose(spreads, 0.0, atol=1e-4)
    assert answer["weights"][0] == weights[0] and answer["spreads"][0] == pytest.approx(0.0, abs=1e-4)
    assert math.isnan(answer["spreads"][1])  # nothing there

    path = tmp_path / "map.svdb"
    m.save(path)
    loaded = slamvdb.load_map(path)
    assert loaded.num_semantic_voxels == m.num_semantic_voxels
    p2, e2, c2 = loaded.semantic_voxels()
    assert np.array_equal(p2, positions) and np.array_equal(c2, counts)
    assert np.allclose(e2, embeddings)


def test_float16_features_fuse_as_their_float32_values(tmp_path):
    """A float16 array is fused in fp16 (not widened first) and gives the map its float32 values give."""
    rng = np.random.default_rng(4)
    half = (rng.random((48, 64, 16)) - 0.25).astype(np.float16)
    a, b = build(tmp_path, half), build(tmp_path, half.astype(np.float32))
    pa, ea, ca = a.semantic_voxels()
    pb, eb, cb = b.semantic_voxels()
    assert len(pa) > 50
    assert np.array_equal(pa, pb) and np.array_equal(ea, eb) and np.array_equal(ca, cb)
    # Strided float16 (not contiguous) is read correctly too.
    wide = np.zeros((48, 64, 32), dtype=np.float16)
    wide[:, :, ::2] = half
    c = build(tmp_path, wide[:, :, ::2])
    assert np.array_equal(c.semantic_voxels()[1], ea)


def test_errors_are_python_exceptions(tmp_path):
    m = build(tmp_path)
    with pytest.raises(slamvdb.Error, match="16-d"):
        m.search(np.ones(8, dtype=np.float32))
    with pytest.raises(slamvdb.Error, match="no such file"):
        slamvdb.load_map(tmp_path / "missing.svdb")


def test_composite_query_and_simulated_text():
    grass = slamvdb.simulated_text_embedding("grass", dim=64)
    tree = slamvdb.simulated_text_embedding("tree", dim=64)
    q = slamvdb.composite_query([grass], [tree])
    assert q.shape == (64,) and math.isclose(float(np.linalg.norm(q)), 1.0, rel_tol=1e-5)
    assert float(q @ grass) > float(q @ tree)


def test_classify_with_a_query_set_file(tmp_path):
    m = build(tmp_path)
    classes = []
    for k, name in enumerate(["rough", "obstacle", "void"]):
        v = [0.0] * 16
        v[[3, 5, 7][k]] = 1.0
        classes.append({"name": name, "rgb": [k, k, k], "void": name == "void", "vector": v})
    path = tmp_path / "queries.json"
    path.write_text(json.dumps({"format": "slamvdb-query-set", "version": 1, "model_id": "test-space", "dim": 16,
                                "classes": classes}))
    queries = slamvdb.QuerySet.load(path)
    assert queries.names == ["rough", "obstacle", "void"] and queries.vectors.shape == (3, 16)
    result = m.classify(queries)
    assert result["names"] == queries.names
    assert (result["classes"] == 0).all()  # every voxel saw "rough" (component 3)
    assert np.allclose(result["scores"], 1.0, atol=1e-3)
    # Confidence: margin 1 (cosine 1 against 0), damped by n / (n + 2), no spread between identical views.
    counts = result["counts"].astype(np.float32)
    assert np.allclose(result["confidences"], counts / (counts + 2), atol=1e-3)

    # Search results carry the same: weights, spreads, and with the query set class and confidence.
    q = np.zeros(16, dtype=np.float32)
    q[3] = 1.0
    found = m.search_details(q, top_k=20, queries=queries)
    assert found["names"] == queries.names and len(found["positions"]) == 20
    assert np.array_equal(found["weights"], found["counts"].astype(np.float32))
    assert (found["classes"] == 0).all()
    by_position = {tuple(p): c for p, c in zip(result["positions"], result["confidences"])}
    for p, c in zip(found["positions"], found["confidences"]):
        assert c == pytest.approx(by_position[tuple(p)], abs=1e-4)
    plain = m.search_details(q, top_k=20)
    assert "classes" not in plain and np.array_equal(plain["scores"], found["scores"])
