"""The provenance block a report states: software, machine, command and input hashes."""
from __future__ import annotations

import hashlib
import json

from railcal.provenance import file_sha256, input_hashes, provenance


def test_input_hashes_are_each_files_sha256_relative_to_the_root(tmp_path):
    (tmp_path / "runs").mkdir()
    (tmp_path / "campaign.toml").write_bytes(b"format = 1\n")
    (tmp_path / "runs" / "b.csv").write_bytes(b"time\n0\n")
    (tmp_path / "runs" / "a.csv").write_bytes(b"")
    hashes = input_hashes([tmp_path / "campaign.toml", tmp_path / "runs"], root=tmp_path)
    assert list(hashes) == ["campaign.toml", "runs/a.csv", "runs/b.csv"]
    assert hashes["runs/b.csv"] == hashlib.sha256(b"time\n0\n").hexdigest()
    assert hashes["runs/a.csv"] == hashlib.sha256(b"").hexdigest() == file_sha256(tmp_path / "runs" / "a.csv")


def test_provenance_names_railcal_its_requirements_the_machine_and_the_command(tmp_path):
    f = tmp_path / "x.json"
    f.write_text("{}")
    block = provenance([f], root=tmp_path, argv=["railcal", "run", "c"], seeds={"pso": 3})
    json.dumps(block)  # a JSON value throughout
    assert block["railcal"]["version"]
    assert {"numpy", "scipy", "exudyn", "fmpy", "casadi"} <= set(block["packages"])
    assert all(v for v in block["packages"].values())
    assert block["command"] == ["railcal", "run", "c"] and block["seeds"] == {"pso": 3}
    assert block["inputs_sha256"] == {"x.json": hashlib.sha256(b"{}").hexdigest()}
    assert block["machine"]["cpus"] >= 1 and block["time_utc"].endswith("+00:00")
    commit = block["railcal"]["commit"]
    assert commit is None or len(commit) == 40
