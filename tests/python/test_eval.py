"""The metrics of `kestrel compare` from Python: per frame and per region, as records, with the
same numbers the CLI prints."""
import json
import os
import pathlib

import numpy as np
import pytest

import kestrel
from conftest import cli


def test_compare_records_equal_the_cli_json(scene):
    # The noisy frames against the reference: the input's error.
    result = kestrel.compare(scene["noisy"], scene["ref"])
    rc, out, err = cli("compare", scene["noisy"], scene["ref"], "--json")
    assert rc == 0, err
    assert result == json.loads(out)
    frames = result["frames"]
    assert [f["frame"] for f in frames] == [1, 2, 3, 4]
    assert frames[0]["temporal"] is None and frames[1]["temporal"] > 0
    assert all(f["relMse"] > 0 and 0 < f["ssim"] < 1 for f in frames)
    # Records a DataFrame takes: every row has the same keys.
    assert len({tuple(sorted(f)) for f in frames}) == 1
    assert kestrel.compare(scene["noisy"], scene["ref"], frames="2-3")["mean"]["frames"] == 2


def test_compare_regions_equal_the_cli(scene):
    rows = kestrel.compare_regions(scene["noisy"], scene["ref"], scene["noisy"], "1-4")
    rc, out, err = cli("compare", scene["noisy"], scene["ref"], "--frames", "1-4",
                       "--regions", scene["noisy"], "--json")
    assert rc == 0, err
    expected = json.loads(out)["regions"]
    assert {r["region"] for r in rows} == set(expected)
    for r in rows:
        assert {k: v for k, v in r.items() if k != "region"} == expected[r["region"]]
    whole = next(r for r in rows if r["region"] == "all")
    assert whole["share"] == 1


def test_compare_images_and_read_exr(scene):
    ref = kestrel.read_exr(scene["ref"].replace("####", "0001"))
    noisy = kestrel.read_exr(scene["noisy"].replace("####", "0001"))
    assert ref.shape == (27, 48, 3) and ref.dtype == np.float32
    same = kestrel.compare_images(ref, ref)
    assert same["relMse"] == 0 and same["psnr"] == 100
    worse = kestrel.compare_images(noisy, ref)
    first = kestrel.compare(scene["noisy"], scene["ref"], frames=[1])["frames"][0]
    assert worse["relMse"] == pytest.approx(first["relMse"], rel=1e-12)
    with pytest.raises(kestrel.Error, match="differ in size"):
        kestrel.compare_images(ref[:10], ref)


def test_missing_frame_is_a_frame_error(scene, tmp_path):
    with pytest.raises(kestrel.FrameError, match="frame_0007.exr"):
        kestrel.compare(scene["noisy"], scene["ref"], frames=[1, 7])
