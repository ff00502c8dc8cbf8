"""A map file read with Python's sqlite3, zlib and numpy alone, as the README's "Map file schema"
describes it: the semantic voxels (world positions, embeddings, counts) and the occupied voxels
come out as `slamvdb export` writes them. No project code is imported (slamvdb is not on the path).

Run by CTest (Python.MapFileSchema) with SLAMVDB_CLI naming the command-line program.
"""
import os
import sqlite3
import subprocess
import sys
import zlib

import numpy as np
import pytest

CLI = os.environ.get("SLAMVDB_CLI", "slamvdb")


def cli(*args):
    subprocess.run([CLI, "--quiet", *map(str, args)], check=True, stdout=subprocess.DEVNULL)


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """A small SIMULATED drive mapped in several submaps (so that cells are shared), and its exports."""
    d = tmp_path_factory.mktemp("schema")
    cli("synth", d / "seq", "--length", 30, "--image-size", "160x100", "--camera-rate", 2)
    cli("map", d / "seq", "-o", d / "m.svdb", "--dim", 16, "--feature-size", "48x30", "--submap-length", 10)
    cli("export", d / "m.svdb", "-o", d / "e.npy", "-o", d / "e.ply", "--ascii")
    return d


# ---- the reader: what a user writes from the README's schema ----
def read_map(path):
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    assert db.execute("PRAGMA application_id").fetchone()[0] == 0x53564442  # "SVDB"
    version = db.execute("PRAGMA user_version").fetchone()[0]
    meta = dict(db.execute("SELECT key, value FROM meta"))
    assert version == 5 and meta["format_version"] == "5", "this reader knows format version 5"
    voxel = float(meta["voxel_size"])
    cell = float(meta["index_cell_size"]) or voxel  # 0: the voxel size
    dim = int(meta["semantic_dim"])
    dtype = np.float16 if meta["semantic_precision"] == "fp16" else np.float32
    submaps = []
    for sid, pose in db.execute("SELECT id, pose FROM submaps ORDER BY id"):
        T = np.frombuffer(pose, dtype="<f8").reshape(4, 4, order="F")  # column-major T_world_submap
        keys, counts, embeddings, stats = [], [], [], []
        for k, c, e, st in db.execute(
                "SELECT keys, counts, embeddings, stats FROM semantics WHERE submap = ? ORDER BY chunk", (sid,)):
            keys.append(np.frombuffer(k, dtype="<i4").reshape(-1, 3))
            counts.append(np.frombuffer(c, dtype="<u4"))
            embeddings.append(np.frombuffer(e, dtype=dtype).reshape(-1, dim))
            stats.append(np.frombuffer(st, dtype="<f4").reshape(-1, 2))  # weight sum, spread (NaN: unknown)
        blocks, log_odds = [], []
        for bx, by, bz, blob in db.execute("SELECT bx, by, bz, log_odds FROM occupancy WHERE submap = ?", (sid,)):
            blocks.append((bx, by, bz))
            log_odds.append(np.frombuffer(zlib.decompress(blob, -15), dtype="<f4"))  # raw deflate, 512 values
        submaps.append(dict(T=T, keys=np.concatenate(keys) if keys else np.zeros((0, 3), np.int32),
                            counts=np.concatenate(counts) if counts else np.zeros(0, np.uint32),
                            embeddings=np.concatenate(embeddings) if embeddings else np.zeros((0, dim), dtype),
                            stats=np.concatenate(stats) if stats else np.zeros((0, 2), np.float32),
                            blocks=np.array(blocks, dtype=np.int64).reshape(-1, 3), log_odds=np.array(log_odds)))
    return meta, voxel, cell, submaps


def read_sessions(path):
    """The sessions (format version 4 and later): id -> (name, source, time range, submap ids)."""
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    sessions = {sid: (name, source, (t0, t1), [])
                for sid, name, source, t0, t1 in db.execute("SELECT id, name, source, time_begin, time_end FROM sessions")}
    for submap, session in db.execute("SELECT submap, session FROM submap_sessions ORDER BY submap"):
        sessions[session][3].append(submap)
    return sessions


def world_cells(T, keys, voxel, cell):
    """Index cells of voxel keys of a submap: the voxel centre moved into the world, floored."""
    centres = (keys.astype(np.float64) + 0.5) * voxel
    world = centres @ T[:3, :3].T + T[:3, 3]
    return np.floor(world * (1.0 / cell)).astype(np.int64)


def cell_ids(cells):
    """One int64 per cell (cells within +-2^20 of the origin), for sorting and grouping."""
    c = cells + (1 << 20)
    return (c[:, 0] << 42) | (c[:, 1] << 21) | c[:, 2]


def semantic_cells(voxel, cell, submaps):
    """Index cells with their summed count and count-weighted mean embedding over every submap."""
    ids = np.concatenate([cell_ids(world_cells(s["T"], s["keys"], voxel, cell)) for s in submaps])
    counts = np.concatenate([s["counts"] for s in submaps]).astype(np.float64)
    embeddings = np.concatenate([s["embeddings"] for s in submaps]).astype(np.float64)
    unique, group = np.unique(ids, return_inverse=True)
    total = np.zeros(len(unique))
    np.add.at(total, group, counts)
    mean = np.zeros((len(unique), embeddings.shape[1]))
    np.add.at(mean, group, embeddings * counts[:, None])
    return dict(zip(unique.tolist(), zip(total.astype(np.int64).tolist(), mean / total[:, None])))


def occupied_cells(meta, voxel, cell, submaps):
    """Ids of the world cells whose combined log-odds is occupied: per submap the maximum of its
    known voxels in a cell, across submaps (in id order) the sum, clamped. Unknown voxels are NaN."""
    lo, hi = np.float32(meta["clamp_min"]), np.float32(meta["clamp_max"])
    i = np.arange(512)
    inside = np.stack([i & 7, (i >> 3) & 7, i >> 6], axis=1)  # x fastest, then y, then z
    world_ids, world_values = np.zeros(0, np.int64), np.zeros(0, np.float32)
    for s in submaps:
        keys = (s["blocks"][:, None, :] * 8 + inside[None, :, :]).reshape(-1, 3)
        values = s["log_odds"].reshape(-1).astype(np.float32)
        known = ~np.isnan(values)
        ids, values = cell_ids(world_cells(s["T"], keys[known], voxel, cell)), values[known]
        if len(ids) == 0:
            continue
        order = np.argsort(ids, kind="stable")
        ids, values = ids[order], values[order]
        starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
        own_ids, own_max = ids[starts], np.maximum.reduceat(values, starts)
        merged = np.union1d(world_ids, own_ids)
        old = np.full(len(merged), np.nan, np.float32)
        new = np.full(len(merged), np.nan, np.float32)
        old[np.searchsorted(merged, world_ids)] = world_values
        new[np.searchsorted(merged, own_ids)] = own_max
        both = ~np.isnan(old) & ~np.isnan(new)
        world_values = np.where(np.isnan(old), new, old)
        world_values[both] = np.clip(old[both] + new[both], lo, hi)
        world_ids = merged
    return set(world_ids[world_values >= np.float32(meta["occupied_threshold"])].tolist())


def test_a_map_reads_with_sqlite_and_numpy_alone(made):
    meta, voxel, cell, submaps = read_map(made / "m.svdb")
    assert len(submaps) >= 2
    # One drive: one session, named after the file, holding every submap over the drive's time.
    sessions = read_sessions(made / "m.svdb")
    assert list(sessions) == [0] and sessions[0][0] == "m" and sessions[0][1] == meta["source"]
    assert len(sessions[0][3]) == len(submaps) and sessions[0][2][0] < sessions[0][2][1]
    # The paper's rule (the default, recorded in meta) weighs every view 1: the weight sums are the counts.
    assert meta["fusion"] == "paper"
    for s in submaps:
        assert len(s["stats"]) == len(s["counts"])
        np.testing.assert_array_equal(s["stats"][:, 0], s["counts"].astype(np.float32))
        assert np.all(s["stats"][:, 1] >= 0)  # fused from observations: spreads known
    assert sum(len(s["counts"]) for s in submaps) == sum(
        int(n) for (n,) in sqlite3.connect(made / "m.svdb").execute("SELECT semantic_voxels FROM submaps"))

    # Semantic voxels against `export -o e.npy` (index cells in key order: positions, embeddings, counts).
    semantic = semantic_cells(voxel, cell, submaps)
    positions = np.load(made / "e.positions.npy")
    embeddings = np.load(made / "e.npy")
    counts = np.load(made / "e.counts.npy")
    assert len(semantic) == len(positions) > 100
    exported = np.floor(positions.astype(np.float64) / cell).astype(np.int64)
    np.testing.assert_allclose(positions, (exported + 0.5) * cell, atol=1e-4)  # cell centres, world frame
    for c, e, n in zip(cell_ids(exported).tolist(), embeddings, counts):
        total, mean = semantic[c]
        assert total == n
        np.testing.assert_allclose(mean, e, atol=2e-3)
    assert any(len(s["keys"]) for s in submaps[1:]) and len(semantic) < sum(len(s["keys"]) for s in submaps)

    # Occupied voxels: the PLY holds every occupied world cell and every semantic cell (count > 0).
    occupied = occupied_cells(meta, voxel, cell, submaps)
    with open(made / "e.ply") as f:
        header = []
        while (line := f.readline().strip()) != "end_header":
            header.append(line)
        rows = np.loadtxt(f, ndmin=2)
    assert "property float x" in header
    ply_cells = cell_ids(np.floor(rows[:, :3] / cell).astype(np.int64))
    assert len(occupied) > 1000 and len(set(ply_cells.tolist())) == len(ply_cells)
    assert set(ply_cells.tolist()) == occupied | set(semantic)
    assert set(ply_cells[rows[:, 6] == 0].tolist()) == occupied - set(semantic)  # grey: occupied, no embedding
    assert "slamvdb" not in sys.modules
