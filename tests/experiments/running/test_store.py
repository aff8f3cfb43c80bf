"""The run store's records (crowd_env.experiments.running.store, issue 37 item 10): a record lacking what its reader
needs is refused naming the file (or the record) and what is missing, before anything is written; the results
table and the summary are written atomically, like the run records."""
import json

import numpy as np
import pytest

from crowd_env.errors import RunStoreError
from crowd_env.experiments.validation.bottleneck import run_sweep, summarise, write_results, write_summary
from crowd_env.experiments.running.store import RunStore, normalise_record


def _record(b=1.0, n=10, seed=0, js=1.8):
    return {"width_m": b, "n_pedestrians": n, "seed": seed, "specific_flow_per_m_s": js, "flow_per_s": js * b,
            "complete": True, "stalled": False, "stall_time_s": np.nan, "partial_specific_flow_per_m_s": js,
            "partial_flow_per_s": js * b, "n_evacuated": n, "n_passages": n, "min_gap_m": -1e-4,
            "density_front_per_m2": 3.0, "density_inside_per_m2": 1.5, "wall_time_s": 1.0}


def _task(b=1.0, n=10, seed=0):
    return {"width_m": b, "n_pedestrians": n, "seed": seed, "geometry": {}, "params": {}, "max_time_s": 60.0}


class _Unprintable:
    """A value the CSV writer cannot turn into text: the write fails half way through the table."""

    def __str__(self):
        raise RuntimeError("killed while writing")


@pytest.mark.parametrize("record, match", [
    ({}, r"^run record: the run record lacks \['n_pedestrians', 'complete \(or n_passages / n_evacuated"),
    ({"n_pedestrians": 10}, r"lacks \['complete \(or n_passages / n_evacuated"),
    ({"n_pedestrians": None, "complete": True}, r"the run record's n_pedestrians must be an integer, got None"),
    ({"n_pedestrians": 10, "n_evacuated": "ten"}, r"n_evacuated must be an integer, got 'ten'"),
    ([1, 2], r"a run record must be a JSON object \(dict\), got list"),
])
def test_normalise_record_names_what_a_record_lacks(record, match):
    """``normalise_record({})`` raised "TypeError: int() argument must be ... not 'NoneType'"."""
    with pytest.raises(RunStoreError, match=match):
        normalise_record(record)


def test_stored_file_lacking_fields_is_named_on_load(tmp_path):
    store = RunStore(tmp_path)
    path = store.path(_task())
    path.write_text("{}")
    with pytest.raises(RunStoreError, match=rf"^{path}: the run record lacks \['n_pedestrians'.*delete its file"):
        store.load(_task())
    with pytest.raises(RunStoreError, match=rf"{path} \(not written\): the run record lacks \['n_pedestrians'"):
        store.save(_task(), {"width_m": 1.0})
    assert path.read_text() == "{}"  # the refused record was not written
    tasks = RunStore(tmp_path / "t", keyed_by="task")
    task = dict(_task(), params={"social_strength_n": 1.0, "social_range_m": 0.1})
    tasks.path(task).write_text("[]")
    with pytest.raises(RunStoreError, match=r"not a stored task"):
        tasks.load(task)


def test_record_missing_the_flow_names_its_file_before_results_csv_is_rewritten(tmp_path):
    """A stored record without ``specific_flow_per_m_s`` rewrote results.csv with empty cells, then raised
    KeyError in the summary."""
    store = RunStore(tmp_path)
    good, bad = _task(seed=0), _task(seed=1)
    store.save(good, _record(seed=0))
    broken = {k: v for k, v in _record(seed=1).items() if k != "specific_flow_per_m_s"}
    store.path(bad).write_text(json.dumps(broken))
    write_results([_record(seed=0), _record(seed=1)], tmp_path)
    before = (tmp_path / "results.csv").read_text()
    with pytest.raises(RunStoreError, match=rf"^{store.path(bad)}: the run record lacks \['specific_flow_per_m_s'\]"):
        run_sweep([good, bad], tmp_path, jobs=1)  # both stored: nothing runs, the records are loaded
    records = [_record(seed=0), broken]
    for write in (lambda: write_results(records, tmp_path), lambda: summarise(records)):
        with pytest.raises(RunStoreError, match=r"^records\[1\] \(b = 1\.0, N = 10, seed 1\): the run record lacks "
                                                r"\['specific_flow_per_m_s'\]"):
            write()
    assert (tmp_path / "results.csv").read_text() == before  # untouched


def test_results_and_summary_are_written_atomically(tmp_path):
    """A write that fails half way through leaves the previous table whole and no temporary file."""
    records = [_record(b=1.0, seed=s, js=1.8 + 0.1 * s) for s in range(3)]
    write_results(records, tmp_path)
    rows = summarise(records)
    path = write_summary(rows, tmp_path)
    results, summary = (tmp_path / "results.csv").read_text(), path.read_text()
    assert len(results.splitlines()) == 4 and "1.9" in results
    assert len(summary.splitlines()) == 2
    with pytest.raises(RuntimeError, match="killed while writing"):
        write_results(records[:2] + [dict(records[2], wall_time_s=_Unprintable())], tmp_path)
    with pytest.raises(RuntimeError, match="killed while writing"):
        write_summary([dict(rows[0], min_gap_m=_Unprintable())], tmp_path)
    assert (tmp_path / "results.csv").read_text() == results
    assert path.read_text() == summary
    assert not list(tmp_path.glob(".*tmp"))


def test_a_folder_from_before_a_parameter_existed_stays_valid_and_its_tasks_resolve(tmp_path):
    """Model parameters at their default count as absent: a config.json or a stored task written before a
    parameter was added (so without it) matches today's, while any value that changes the model is refused."""
    from crowd_env.walking import ModelParams
    from crowd_env.experiments.validation.bottleneck import params_dict
    from crowd_env.experiments.running.store import config_hash, task_key

    params = params_dict(ModelParams(social_strength_n=331.5))
    newest = "ttc_strength_m2_s2"  # added after folders of runs existed: theirs lack it
    old_params = {k: v for k, v in params.items() if k != newest}
    today = {"geometry": {"width_m": 1.0}, "params": params, "max_time_s": 60.0}
    (tmp_path / "config.json").write_text(json.dumps(dict(today, params=old_params)))
    RunStore(tmp_path, today)  # accepted
    task = {"width_m": 1.0, "n_pedestrians": 10, "seed": 0, "params": params}
    old_task = dict(task, params=old_params)
    assert task_key(task) == task_key(old_task) and config_hash(today) == config_hash(dict(today, params=old_params))
    store = RunStore(tmp_path / "t", None, keyed_by="task")
    store.runs_dir.mkdir(parents=True, exist_ok=True)
    store.path(old_task).write_text(json.dumps({"task": old_task, "record": _record(n=10)}))
    assert store.load(task)["n_pedestrians"] == 10  # the old file is today's task
    changed = dict(today, params=dict(params, social_range_m=0.3))
    with pytest.raises(RunStoreError, match="params.social_range_m"):
        RunStore(tmp_path, changed)
    # a parameter set away from its default is part of the configuration
    assert config_hash(dict(today, params=dict(params, **{newest: 2.5}))) != config_hash(today)
