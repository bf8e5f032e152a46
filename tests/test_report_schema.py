"""The unwrap report validates against the JSON schema shipped in the package (uvbake/atlas/report_schema.json)."""

import json
from importlib import resources

import pytest

from conftest import SAMPLE_SCENES

jsonschema = pytest.importorskip("jsonschema")


@pytest.fixture(scope="module")
def schema():
    s = json.loads((resources.files("uvbake.atlas") / "report_schema.json").read_text())
    jsonschema.Draft202012Validator.check_schema(s)
    return s


def _report(**kw):
    from uvbake.atlas.pipeline import unwrap

    # through JSON, as a user reads it
    return json.loads(json.dumps(unwrap(SAMPLE_SCENES / "scene.ply", texture_size_px=128, **kw).report))


def test_report_validates(schema):
    report = _report()
    jsonschema.validate(report, schema)
    assert report["charts_final"] == len(report["charts"]) == 8


def test_cli_report_validates(schema, tmp_path):
    from uvbake.cli import main

    out = tmp_path / "r.json"
    assert main([str(SAMPLE_SCENES / "disk_holes.ply"), "-o", str(tmp_path / "m.glb"), "--json", str(out),
                 "--texture-size", "128", "-q"]) == 0
    report = json.loads(out.read_text())
    jsonschema.validate(report, schema)
    assert report["outputs"] and all(isinstance(p, str) for p in report["outputs"])


def test_schema_rejects_a_wrong_report(schema):
    report = _report()
    for broken in (
        {k: v for k, v in report.items() if k != "valid"},                     # a required field missing
        report | {"charts_final": "8"},                                        # a count as text
        report | {"atlas": report["atlas"] | {"efficiency": 1.5}},             # packing above 100 %
        report | {"charts": [report["charts"][0] | {"angle_distortion_max": 0.5}]},  # sigma1/sigma2 < 1
    ):
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(broken, schema)


def test_version_exits_0(capsys):
    from uvbake import __version__
    from uvbake.cli import main

    try:
        status = main(["--version"])
    except SystemExit as exc:                   # argparse's version action exits
        status = exc.code
    assert status == 0
    assert capsys.readouterr().out.strip() == f"uvbake {__version__}"


def test_every_option_has_help():
    import argparse

    from uvbake.cli import parser

    top = parser()
    sub = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    missing = [f"uvbake {name} {'/'.join(a.option_strings) or a.dest}"
               for name, p in sub.choices.items() for a in p._actions
               if not isinstance(a, argparse._HelpAction) and not (a.help or "").strip()]
    assert missing == []


def test_report_of_a_rectangular_atlas_validates(schema):
    from uvbake.atlas.pipeline import unwrap

    report = json.loads(json.dumps(unwrap(SAMPLE_SCENES / "disk_holes.ply", texture_size_px=(256, 128)).report))
    jsonschema.validate(report, schema)
    assert report["options"]["texture_size_px"] == [256, 128]
    assert (report["atlas"]["texture_size_px"], report["atlas"]["width_px"], report["atlas"]["height_px"]) == (256, 256, 128)
