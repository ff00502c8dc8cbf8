"""`slamvdb serve` against its OpenAPI file (docs/openapi.yaml): a real server on an ephemeral
loopback port, every documented route and status called, every answer validated against the schema
of its route and status by a small validator of the JSON Schema subset the file uses (Python's
standard library and Debian's python3-yaml; no PyPI)."""
import json
import os
import pathlib
import signal
import subprocess
import urllib.error
import urllib.request

import numpy as np
import pytest
import yaml

import slamvdb

ROOT = pathlib.Path(__file__).resolve().parents[2]
SPEC = yaml.safe_load((ROOT / "docs" / "openapi.yaml").read_text())


def resolve(schema):
    while "$ref" in schema:
        node = SPEC
        for part in schema["$ref"].lstrip("#/").split("/"):
            node = node[part]
        schema = node
    return schema


def validate(value, schema, where="$"):
    """Raises AssertionError naming the place where `value` breaks `schema` (the subset used)."""
    schema = resolve(schema)
    if value is None:
        assert schema.get("nullable", False), f"{where}: null where {schema} is not nullable"
        return
    for part in schema.get("allOf", []):
        validate(value, part, where)
    if "oneOf" in schema:
        passed = 0
        for option in schema["oneOf"]:
            try:
                validate(value, option, where)
                passed += 1
            except AssertionError:
                pass
        assert passed == 1, f"{where}: {value!r} matches {passed} of oneOf"
        return
    kind = schema.get("type")
    checks = {
        "object": lambda v: isinstance(v, dict),
        "array": lambda v: isinstance(v, list),
        "string": lambda v: isinstance(v, str),
        "integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
        "number": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool),
        "boolean": lambda v: isinstance(v, bool),
    }
    if kind:
        assert checks[kind](value), f"{where}: {value!r} is not {kind}"
    if "enum" in schema:
        assert value in schema["enum"], f"{where}: {value!r} not in {schema['enum']}"
    if "minimum" in schema:
        assert value >= schema["minimum"], f"{where}: {value} < {schema['minimum']}"
    if "maximum" in schema:
        assert value <= schema["maximum"], f"{where}: {value} > {schema['maximum']}"
    if "minLength" in schema:
        assert len(value) >= schema["minLength"], where
    if "maxLength" in schema:
        assert len(value) <= schema["maxLength"], where
    if kind == "array":
        assert len(value) >= schema.get("minItems", 0), where
        assert len(value) <= schema.get("maxItems", len(value)), where
        for i, item in enumerate(value):
            if "items" in schema:
                validate(item, schema["items"], f"{where}[{i}]")
    if kind == "object":
        for key in schema.get("required", []):
            assert key in value, f"{where}: required '{key}' missing"
        props = schema.get("properties", {})
        if schema.get("additionalProperties") is False:
            extra = set(value) - set(props)
            assert not extra, f"{where}: undocumented {sorted(extra)}"
        for key, sub in props.items():
            if key in value:
                validate(value[key], sub, f"{where}.{key}")


def response_schema(path, method, status):
    op = SPEC["paths"][path][method]
    response = resolve(op["responses"][str(status)])
    return response["content"]["application/json"]["schema"]


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("serve")
    m = slamvdb.Map(voxel_size=0.25, dim=16, precision="fp16", submap_length=0, model_id="test-space")
    pts = np.array([(x, y, 0.01) for x in np.arange(-4, 4, 0.2) for y in np.arange(-4, 4, 0.2)], dtype=np.float32)
    T = np.eye(4)
    T[2, 3] = 1.5
    m.integrate_scan(0.0, pts - np.array([0, 0, 1.5], dtype=np.float32), T)
    T_world_camera = np.eye(4)
    T_world_camera[:3, :3] = np.array([[0, -1, 0], [-1, 0, 0], [0, 0, -1]], dtype=float)  # looking down
    T_world_camera[:3, 3] = [0.0, 0.0, 5.0]
    features = np.zeros((48, 64, 16), dtype=np.float32)
    features[:, :32, 3] = 1.0
    features[:, 32:, 5] = 1.0
    m.fuse_features(1.0, features, {"fx": 20.0, "fy": 20.0, "cx": 31.5, "cy": 23.5}, T_world_camera)
    m.finish()
    path = tmp / "m.svdb"
    m.save(path)
    proc = subprocess.Popen([os.environ["SLAMVDB_CLI"], "serve", str(path), "--port", "0", "--ignore-model-id",
                             "--max-body", "4096"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    port = None
    for line in proc.stdout:  # log lines may come first
        if "http://" in line:
            port = int(line.split("http://", 1)[1].split("/", 1)[0].rsplit(":", 1)[1])
            break
    assert port, "serve printed no address"
    yield f"http://127.0.0.1:{port}"
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=30) == 0


def call(base, method, path, body=None):
    data = body.encode() if isinstance(body, str) else (json.dumps(body).encode() if body is not None else None)
    request = urllib.request.Request(base + path, data=data, method=method,
                                     headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(request, timeout=30) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


@pytest.mark.parametrize("method,path,body,status", [
    ("GET", "/healthz", None, 200),
    ("GET", "/api/info", None, 200),
    ("GET", "/api/submaps", None, 200),
    ("POST", "/api/at", {"points": [[0.5, 0.5, 0.05], [50, 50, 50]], "embedding": True}, 200),
    ("POST", "/api/at", {"points": [[0.5, 0.5]]}, 400),
    ("PUT", "/api/at", None, 405),
    ("POST", "/api/query", {"text": "grass", "top_k": 5}, 200),
    ("POST", "/api/query", {"text": ["grass", "dirt"], "not": "tree", "top_k": 0, "threshold": -1, "exact": True}, 200),
    ("POST", "/api/query", {"vector": [[0.0] * 3 + [1.0] + [0.0] * 12], "top_k": 3}, 200),
    ("POST", "/api/query", {"text": "grass", "top_k": 5, "region": {"bbox": [-1, -1, -1, 1, 1, 1]}}, 200),
    ("POST", "/api/query", {"text": "grass", "region": {"near": [0.5, 0.5], "radius": 1.5}}, 200),
    ("POST", "/api/query", {"text": "grass", "region": {"near": [0.5, 0.5]}}, 400),
    ("POST", "/api/query", {"text": "grass", "top_k": "five"}, 400),
    ("POST", "/api/query", "not json", 400),
    ("POST", "/api/query", {"text": "x" * 5000}, 413),
    ("DELETE", "/api/query", None, 405),
    ("POST", "/healthz", {}, 405),
    ("POST", "/api/info", {}, 405),
    ("GET", "/api/classes?bbox=-1,-1,-1,1,1,1", None, 400),  # this server has no --queries
    ("GET", "/api/classes", None, 400),
    ("POST", "/api/classes", {}, 405),
    ("GET", "/api/points?lod=9", None, 400),
    ("GET", "/api/points?limit=1", None, 413),
    ("POST", "/api/points", {}, 405),
    ("GET", "/api/events?since=1", None, 400),
    ("POST", "/", {}, 405),
])
def test_answers_follow_the_openapi_file(server, method, path, body, status):
    got, answer = call(server, method, path, body)
    assert got == status, answer
    route = path.split("?", 1)[0]
    validate(answer, response_schema(route, method.lower() if method.lower() in SPEC["paths"][route] else
                                     next(iter(SPEC["paths"][route])), status))
    if status == 200 and path == "/api/query":
        assert answer["encoder"]["simulated"] is True
        assert [r["rank"] for r in answer["results"]] == list(range(1, answer["count"] + 1))
        scores = [r["score"] for r in answer["results"]]
        assert scores == sorted(scores, reverse=True) and answer["count"] > 0


def test_documented_request_fields_are_what_the_server_accepts(server):
    """Every documented request field is known to the server, and an undocumented one is refused."""
    schema = resolve(SPEC["paths"]["/api/query"]["post"]["requestBody"]["content"]["application/json"]["schema"])
    for field in schema["properties"]:
        got, answer = call(server, "POST", "/api/query", {"text": "grass", field: None})
        # null is no valid value of any field: refused naming the field, but never as unknown.
        assert got == 400 and answer["error"]["field"] in (field, "text"), (field, answer)
        assert not answer["error"]["message"].startswith("unknown field"), (field, answer)
    got, answer = call(server, "POST", "/api/query", {"text": "grass", "undocumented": 1})
    assert got == 400 and answer["error"]["field"] == "undocumented"
