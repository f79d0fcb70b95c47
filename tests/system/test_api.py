"""The Python API speaks the scene file's language (issue 36): names, misspelled
keywords, one import, one set of defaults, peaks as rows, documented public names,
deprecated keywords that still work."""

import ast
import csv
import dataclasses
import importlib
import inspect
import re
import subprocess
import sys
import typing
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

import acousim
import hardware
import processing as P
from acousim.scene import parse_scene
from processing.base.errors import InputError
from tests import REPO
from tests.oracles.analytic import plane_wave_snapshot

ROOT = REPO
PACKAGES = {"acousim": acousim, "processing": P, "hardware": hardware}


# --- names: what a scene file names, the constructors take --------------------------


def test_a_sensor_takes_the_array_preset_by_name():
    s = acousim.Sensor(array="urtis_v1")
    # rtis-facts.md: uRTIS v1 has 30 microphones, 3.85 mm apart both ways (5 x 6)
    assert s.array.n_mics == 30 and s.array.is_ura and s.array.grid_shape == (5, 6)
    assert s.array.pitch_m == pytest.approx((3.85e-3, 3.85e-3))
    d = np.diff(np.unique(np.round(s.array.positions_m[:, 1], 6)))
    assert d == pytest.approx(np.full(5, 3.85e-3))


def test_names_mean_the_same_objects_as_in_a_scene_file():
    table = {
        "sensor": {"array": "paper_8x8", "call": "paper", "lidar": {"preset": "hdl32e"}},
        "points": [{"position_m": [1.0, 0.0, 0.0]}],
    }
    from_file = parse_scene(table).sensor
    in_code = acousim.Sensor(array="paper_8x8", call="paper", lidar="hdl32e")
    assert np.array_equal(from_file.array.positions_m, in_code.array.positions_m)
    assert from_file.call == in_code.call
    # the paper's call: linear 20 -> 85 kHz in 1 ms; the HDL-32E: 32 channels
    assert (in_code.call.kind, in_code.call.band_hz, in_code.call.duration_s) == (
        "linear",
        (20e3, 85e3),
        1e-3,
    )
    assert from_file.lidar == in_code.lidar and in_code.lidar.channels == 32


@pytest.mark.parametrize(
    "key,value,close",
    [("array", "urtis", "urtis_v1"), ("call", "papr", "paper"), ("lidar", "vlp61", "vlp16")],
)
def test_a_wrong_name_gets_the_scene_files_answer(key, value, close):
    with pytest.raises(InputError) as in_code:
        acousim.Sensor(**{key: value})
    table = {"sensor": {key: {"preset": value} if key == "lidar" else value}}
    table["points"] = [{"position_m": [1.0, 0.0, 0.0]}]
    with pytest.raises(InputError) as in_file:
        parse_scene(table)
    assert f"did you mean {close!r}" in in_code.value.reason
    assert in_code.value.reason == in_file.value.reason


def test_materials_by_name_as_in_a_scene_file():
    box = trimesh.creation.box((0.1, 2.0, 2.0))
    plaster = acousim.Material("plaster", reflection=0.5)
    scene = acousim.Scene(
        materials=[plaster],
        meshes=[acousim.MeshItem(box, material="plaster", materials={"x": "default"})],
    )
    mesh = scene.meshes[0]
    assert mesh.material is plaster and mesh.materials["x"] == acousim.Material("default")
    with pytest.raises(InputError, match=r"material = 'plastr': .*did you mean 'plaster'"):
        acousim.Scene(materials=[plaster], meshes=[acousim.MeshItem(box, material="plastr")])


# --- a misspelled keyword: the scene file's answer -----------------------------------


def test_a_misspelled_keyword_is_answered_like_a_misspelled_key():
    with pytest.raises(P.KeywordError) as exc:
        acousim.Sensor(arrray="urtis_v1")
    assert isinstance(exc.value, TypeError) and isinstance(exc.value, InputError)
    assert str(exc.value).startswith(
        "Sensor.arrray: unknown key 'arrray'; did you mean 'array'? (allowed: array, call, "
    )
    table = {"sensor": {"arrray": "urtis_v1"}, "points": [{"position_m": [1.0, 0.0, 0.0]}]}
    with pytest.raises(InputError) as in_file:
        parse_scene(table)
    assert in_file.value.reason.startswith("unknown key 'arrray'; did you mean 'array'?")
    with pytest.raises(P.KeywordError, match=r"Grid.degrees.stepp: .*did you mean 'step'"):
        P.Grid.degrees(stepp=1.0)
    with pytest.raises(P.KeywordError, match=r"doa_spectrum.methd: .*did you mean 'method'"):
        P.doa_spectrum(np.ones((64, 1)), P.paper_8x8(), 3e4, P.Grid.degrees(), methd="das")


def _public(package):
    for name in package.__all__:
        yield name, getattr(package, name)


def _callables():
    """(where, callable) of every public function, constructor and public method."""
    for pkg_name, package in PACKAGES.items():
        for name, obj in _public(package):
            if inspect.isfunction(obj):
                yield f"{pkg_name}.{name}", obj
            elif inspect.isclass(obj) and not issubclass(obj, BaseException):
                if "__init__" in vars(obj):
                    yield f"{pkg_name}.{name}", obj
                for attr, value in vars(obj).items():
                    if not attr.startswith("_") and inspect.isfunction(value):
                        yield f"{pkg_name}.{name}.{attr}", value


def test_every_public_callable_refuses_an_unknown_keyword():
    """Before its body runs: the check needs no other argument."""
    missed = []
    for where, fn in _callables():
        params = inspect.signature(fn).parameters.values()
        if any(p.kind is p.VAR_KEYWORD for p in params):
            continue
        try:
            fn(zzz_no_such_keyword=1)
        except P.KeywordError as exc:
            said = str(exc)  # the allowed keys, or that there are none
            assert "unknown key 'zzz_no_such_keyword'" in said
            assert "(allowed: " in said or "(it takes none)" in said
        except Exception:
            missed.append(where)
        else:
            missed.append(where)
    assert not missed, missed


def test_the_dataset_api_the_readme_names_refuses_an_unknown_keyword_too():
    """`DatasetReader("data/cs").torch()` (README) and the rest of acousim.dataset's
    names: a misspelled keyword gets the scene file's answer (it was a plain
    TypeError)."""
    import acousim.dataset as D

    with pytest.raises(P.KeywordError, match=r"torch\.kyes: .*did you mean 'keys'"):
        D.DatasetReader.torch(None, kyes=["image"])  # checked before the body runs
    missed = []
    for name in D.__all__:
        obj = getattr(D, name)
        if inspect.isclass(obj) and issubclass(obj, BaseException):
            continue
        if not (inspect.isfunction(obj) or "__init__" in vars(obj)):
            continue
        try:
            obj(zzz_no_such_keyword=1)
        except P.KeywordError as exc:
            assert "unknown key 'zzz_no_such_keyword'" in str(exc)
        except Exception:
            missed.append(name)
        else:
            missed.append(name)
    assert not missed, missed


# --- one import; every options type exported ----------------------------------------


def _names_used(text: str) -> set[str]:
    """`acousim.a.b...` attribute chains in the Python code blocks of a document, and
    the calls in its inline code (not a file's attribute such as `acousim.chirp`)."""
    chain = r"(?<![\w\"'./])acousim(?:\.[A-Za-z_]\w*)+"
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    inline = re.findall(r"`([^`\n]+)`", text)
    found = [set(re.findall(chain, b)) for b in blocks]
    found += [{m[:-1] for m in re.findall(chain + r"\(", c)} for c in inline]
    return set().union(*found)


def test_import_acousim_is_enough_for_every_name_the_docs_use():
    docs = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    names = sorted(set().union(*(_names_used(p.read_text()) for p in docs)))
    assert "acousim.process.configure" in names
    names = [n for n in names if not n.startswith("acousim.cli")]  # the command line's modules
    code = f"import acousim\nfor n in {names!r}:\n    eval(n)\nprint('ok')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert out.stdout.strip() == "ok", out.stderr[-2000:]


def test_processing_exports_every_options_type_its_signatures_take():
    missing = set()
    for _, fn in _callables():
        if not fn.__module__.startswith("processing"):
            continue
        target = fn.__init__ if inspect.isclass(fn) else fn
        hints = typing.get_type_hints(inspect.unwrap(target))
        for hint in hints.values():
            for t in (hint, *typing.get_args(hint)):
                mod = getattr(t, "__module__", "")
                if inspect.isclass(t) and mod.startswith("processing"):
                    if t.__name__ not in P.__all__:
                        missing.add(f"{mod}.{t.__name__}")
    assert not missing, missing
    assert P.SubspaceOptions is importlib.import_module("processing.imaging.doa").SubspaceOptions


# --- one set of defaults -------------------------------------------------------------


def test_the_python_defaults_are_the_command_lines():
    from acousim.cli import build_parser
    from acousim.imaging.run import ImagingOptions

    parser = build_parser()
    args = parser.parse_args(["image", "x.h5"])
    assert args.step is None and args.peak_threshold is None  # the declared defaults apply
    assert args.method is None
    image = parser._subparsers._group_actions[0].choices["image"]
    said = re.search(r"\(default: ([\w,-]+)\)", " ".join(image.format_help().split()))
    assert tuple(said.group(1).split(",")) == ImagingOptions().methods
    from acousim.cli.image import CHIRP_CALLS, DRIVE_VIEWS
    from acousim.viz.drive import DRIVE_VIEWS as VIEWS

    assert DRIVE_VIEWS == VIEWS

    assert set(CHIRP_CALLS) == set(P.CALLS)
    cli = ImagingOptions().grid
    for grid in (P.Grid.degrees(), P.ProcessingSettings().grid):
        assert np.array_equal(grid.azimuth_rad, cli.azimuth_rad)
        assert np.array_equal(grid.elevation_rad, cli.elevation_rad)
    assert np.rad2deg(cli.elevation_rad[[0, -1]]) == pytest.approx((-40.0, 40.0))
    assert inspect.signature(P.find_peaks).parameters["threshold_db"].default == (
        ImagingOptions().peak_threshold_db
    )


@pytest.mark.parametrize("method", P.NARROWBAND_METHODS)
def test_an_echo_from_the_pole_is_one_peak(method):
    """Straight below the sensor (a floor echo) every azimuth is one direction: on a
    grid that reaches the pole it is one peak there, not one per azimuth segment."""
    arr, f = P.paper_8x8(), 31250.0
    rng = np.random.default_rng(1)
    x = plane_wave_snapshot(arr, 0.0, -90.0, f)[:, None, None] * np.array([0.5, 1, 0.5])[:, None]
    x = x + 0.01 * (rng.standard_normal(x.shape) + 1j * rng.standard_normal(x.shape))
    grid = P.Grid.degrees(elevation=(-90.0, 90.0))
    power = P.doa_spectrum(x, arr, f, grid, method)
    image = P.Image(power, np.array([0.99, 1.0, 1.01]), grid.elevation_rad, grid.azimuth_rad,
                    method, f)  # fmt: skip
    near_pole = [r for r in image.peaks() if r.elevation_deg < -80]
    assert len(near_pole) == 1 and near_pole[0].elevation_deg == -90.0
    assert image.peaks()[0].elevation_deg == -90.0  # the strongest


@pytest.mark.parametrize("method", ["das", "capon-fbss", "music-fbss"])
def test_an_echo_in_view_is_one_peak_on_the_default_grid(method):
    arr, f = P.paper_8x8(), 31250.0
    rng = np.random.default_rng(2)
    x = plane_wave_snapshot(arr, 20.0, -20.0, f)[:, None, None] * np.array([0.5, 1, 0.5])[:, None]
    x = x + 0.01 * (rng.standard_normal(x.shape) + 1j * rng.standard_normal(x.shape))
    grid = P.Grid.degrees()
    image = P.Image(P.doa_spectrum(x, arr, f, grid, method), np.array([0.99, 1.0, 1.01]),
                    grid.elevation_rad, grid.azimuth_rad, method, f)  # fmt: skip
    (peak,) = image.peaks()
    assert (peak.azimuth_deg, peak.elevation_deg) == (20.0, -20.0)


# --- peaks are rows ------------------------------------------------------------------


def _two_peak_image():
    az, el, rng = np.deg2rad(np.arange(-10, 11, 2.0)), np.deg2rad(np.arange(-6, 7, 2.0)), [1.0, 1.5]
    power = np.full((2, el.size, az.size), 1e-6)
    power[0, 4, 7] = 1.0  # 1.0 m, az +4, el +2
    power[1, 0, 0] = 0.5  # 1.5 m, az -10, el -6: on the grid's corner; -3.01 dB
    return P.Image(power, np.array(rng), el, az, "das", 3e4)


def test_peaks_are_rows_with_the_csv_columns():
    peaks = _two_peak_image().peaks()
    assert len(peaks) == 2 and len(list(peaks)) == 2
    first, second = peaks[0], peaks[1]
    assert isinstance(first, P.PeakRow) and tuple(first.as_dict()) == P.PEAK_COLUMNS
    assert (first.range_m, first.azimuth_deg, first.elevation_deg) == pytest.approx((1, 4, 2))
    a, e = np.deg2rad(4.0), np.deg2rad(2.0)  # x forward, y left, z up
    want = (np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e))
    assert (first.x_m, first.y_m, first.z_m) == pytest.approx(want)
    assert first.level_db == 0.0 and second.level_db == pytest.approx(10 * np.log10(0.5))
    assert (first.on_grid_edge, second.on_grid_edge) == (False, True)
    assert first.method == "das" and first.truth_kind == "" and np.isnan(first.truth_x_m)
    records = peaks.to_records()
    assert [r["range_m"] for r in records] == [1.0, 1.5]
    columns = peaks.as_dict()
    assert tuple(columns) == P.PEAK_COLUMNS and columns["azimuth_deg"] == pytest.approx([4, -10])
    assert all(len(v) == 2 for v in columns.values())
    empty = P.PeakTable()
    assert len(empty) == 0 and tuple(empty.as_dict()) == P.PEAK_COLUMNS
    # neither pandas nor polars imported (in a process of its own: another test's
    # imports, xarray's, would be in this one)
    code = (
        "import sys, processing as P; t = P.PeakTable(); t.to_records(); t.as_dict(); "
        "print('pandas' in sys.modules or 'polars' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "False", out.stderr


def test_the_csv_writes_the_rows_of_peak_table(tmp_path):
    """One declaration: peaks.csv's header is PeakRow's fields and its rows are
    acousim.peak_table's, for a reflector placed by hand in front of a turned sensor."""
    from acousim.export import write_peaks_csv

    yaw, pos = np.deg2rad(30.0), np.array([0.5, -0.2, 0.3])
    rot = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    p_sensor = np.array([1.0, 0.5, 0.2])
    scene = acousim.Scene(
        points=[acousim.PointItem(position_m=tuple(pos + rot @ p_sensor))],
        sensor=acousim.Sensor(
            array="paper_8x8",
            call="paper",
            sample_rate_hz=500e3,
            direct_path=False,
            poses=acousim.Pose(pos, yaw),
        ),  # fmt: skip
        simulation=acousim.Simulation(max_range_m=2.0, snr_db=20.0, absorption=False, seed=5),
    )
    (rec,) = acousim.Simulator(scene).run()
    options = acousim.ImagingOptions(methods=("das",), step_deg=1.0, energy_fraction=0.3)
    (images,) = acousim.image_recordings([rec], options)
    table = acousim.peak_table(rec, images["das"], index=0)
    top = table[0]
    assert top.range_m == pytest.approx(np.linalg.norm(p_sensor), abs=0.03)
    assert top.azimuth_deg == pytest.approx(np.rad2deg(np.arctan2(0.5, 1.0)), abs=1.5)
    world = np.array([top.world_x_m, top.world_y_m, top.world_z_m])
    assert np.linalg.norm(world - (pos + rot @ p_sensor)) < 0.05
    assert top.truth_kind == "point" and top.provenance == "simulated" and top.recording == 0
    path = write_peaks_csv(tmp_path / "peaks.csv", [rec], [images])
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == P.PEAK_COLUMNS and len(rows) == len(table) + 1
    for got, row in zip(rows[1:], table):  # every number in full, no value empty
        for text, value in zip(got, row.as_dict().values()):
            if value is None or (isinstance(value, float) and np.isnan(value)):
                assert text == ""
            elif isinstance(value, float):
                assert float(text) == value  # the same float64, not a rounding of it
            else:
                assert text == str(int(value) if isinstance(value, bool) else value)


# --- documented public names ---------------------------------------------------------


def _documented_constant(package, name: str) -> bool:
    """A `#:` comment above, or a string below, the name's assignment in a module of
    `package`."""
    for path in Path(package.__file__).parent.rglob("*.py"):
        text = path.read_text()
        if name not in text:
            continue
        lines = text.splitlines()
        body = ast.parse(text).body
        for i, node in enumerate(body):
            targets = node.targets if isinstance(node, ast.Assign) else (
                [node.target] if isinstance(node, ast.AnnAssign) else [])  # fmt: skip
            if not any(isinstance(t, ast.Name) and t.id == name for t in targets):
                continue
            above = lines[node.lineno - 2].strip() if node.lineno > 1 else ""
            nxt = body[i + 1] if i + 1 < len(body) else None
            below = isinstance(nxt, ast.Expr) and isinstance(getattr(nxt, "value", None),
                                                             ast.Constant)  # fmt: skip
            if above.startswith("#:") or (above.startswith("#") and "default" in above) or below:
                return True
    return False


def test_every_public_name_has_a_docstring():
    empty = []
    for pkg_name, package in PACKAGES.items():
        for name, obj in _public(package):
            if inspect.isclass(obj) or inspect.isfunction(obj) or inspect.ismodule(obj):
                doc = obj.__dict__.get("__doc__") if inspect.isclass(obj) else obj.__doc__
                generated = doc is not None and doc.startswith(f"{name}(")  # a dataclass's
                if not doc or not doc.strip() or generated:
                    empty.append(f"{pkg_name}.{name}")
            elif not _documented_constant(package, name):
                empty.append(f"{pkg_name}.{name}")
    assert not empty, empty


# --- deprecated keywords -------------------------------------------------------------


def test_doa_spectrums_old_subarray_keyword_still_works_with_a_warning():
    arr, f = P.paper_8x8(), 31250.0
    x = plane_wave_snapshot(arr, 10.0, 5.0, f)[:, None, None] * np.ones((1, 2, 3))
    x = x + 0.01 * np.random.default_rng(3).standard_normal(x.shape)
    grid = P.Grid.degrees(step=5.0)
    new = P.doa_spectrum(x, arr, f, grid, "music-fbss", options=P.SubspaceOptions((4, 4), -0.5, 1))
    with pytest.warns(DeprecationWarning, match=r"doa_spectrum\(subarray=, n_sources=.*options="):
        old = P.doa_spectrum(x, arr, f, grid, "music-fbss", subarray=(4, 4), n_sources=1)
    assert np.array_equal(old, new)
    default = P.doa_spectrum(x, arr, f, grid, "music-fbss")
    assert not np.array_equal(default, new)  # the keyword did something


def test_stft_snapshots_old_keywords_still_work_with_a_warning():
    x = np.random.default_rng(4).standard_normal((4, 2000))
    new = P.stft_snapshot(x, 450e3, stft=P.Stft(window=128, overlap=96),
                          gate=P.BinGate(energy_fraction=0.1))  # fmt: skip
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = P.stft_snapshot(x, 450e3, window=128, overlap=96, energy_fraction=0.1)
    assert {w.category for w in caught} == {DeprecationWarning} and len(caught) == 2
    assert np.array_equal(old.data, new.data) and np.array_equal(old.range_m, new.range_m)


def test_a_scripts_old_keywords_warn_at_its_own_lines(tmp_path):
    """Run as a user runs a script (Python's default warning filters: a
    DeprecationWarning shows only when raised in ``__main__``): each old spelling's
    warning is printed, pointing at the script's own line, whatever wrappers lie
    between (the keyword check, the options folding, the module alias)."""
    script = tmp_path / "old.py"
    script.write_text(
        "import numpy as np\n"
        "import processing as P\n"
        "import acousim\n"
        "x = np.ones((64, 2, 3), complex)\n"
        "grid = P.Grid.degrees(step=10.0)\n"
        "P.doa_spectrum(x, P.paper_8x8(), 3e4, grid, 'music-fbss', subarray=(4, 4))\n"
        "acousim.Simulation(diffraction_order=1)\n"
        "import acousim.core.delays\n"
    )
    run = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=300
    )
    assert run.returncode == 0, run.stderr
    for line, words in ((6, "doa_spectrum(subarray="), (7, "Simulation(diffraction="),
                        (8, "acousim.core.delays")):  # fmt: skip
        assert f"old.py:{line}: DeprecationWarning" in run.stderr, (line, run.stderr)
        assert words in run.stderr


def test_an_old_keyword_beside_its_new_home_is_refused():
    """``subarray=`` and ``options=SubspaceOptions(...)`` both given: which is meant?
    The call is refused, naming both (it used to take the old keyword silently)."""
    x, grid = np.ones((64, 2, 3), complex), P.Grid.degrees(step=10.0)
    opts = P.SubspaceOptions(subarray=(3, 3))
    with pytest.raises(TypeError, match=r"subarray and options= both given"):
        P.doa_spectrum(x, P.paper_8x8(), 3e4, grid, "music-fbss", subarray=(4, 4), options=opts)


def test_the_changelog_names_the_change():
    text = (ROOT / "CHANGELOG.md").read_text()
    assert "## Unreleased" in text and "doa_spectrum(subarray=" in text


# --- typed packages ------------------------------------------------------------------


def test_the_packages_are_marked_typed():
    for package in PACKAGES.values():
        assert (Path(package.__file__).parent / "py.typed").is_file()
    pyproject = (ROOT / "pyproject.toml").read_text()
    assert all(f'{p} = ["py.typed"]' in pyproject for p in PACKAGES)
    assert "mypy" in (ROOT / "Makefile").read_text()


def test_a_users_script_type_checks_against_the_lazy_names(tmp_path):
    """``import acousim`` loads its names on first use; a type checker still sees each
    one's real type (mypy on a user's script: ``acousim.Sensor(...)`` is callable
    and returns a Sensor, an attribute it lacks is caught before running)."""
    mypy = pytest.importorskip("mypy.api", reason="mypy not installed (make lint installs it)")
    script = tmp_path / "user.py"
    script.write_text(
        "import acousim\n"
        "import processing as P\n"
        "s = acousim.Sensor(array='urtis_v1')\n"
        "sim: acousim.Simulator = acousim.Simulator(acousim.Scene(sensor=s))\n"
        "lidar: acousim.Lidar = acousim.Lidar()\n"
        "grid: P.Grid = P.Grid.degrees(step=2.0)\n"
        "reveal_type(s)\n"
        "s.arrray\n"
        "m = acousim.MeshItem('w.stl', material='plaster', materials={'seat': 'felt'})\n"
        "rec = P.load_recording('x.h5')\n"
        "rows: P.PeakTable = acousim.peak_table(rec, P.acoustic_image(rec))\n"
        "opts: acousim.ImagingOptions = acousim.ImagingOptions(step_deg=1.0)\n"
        "reveal_type(acousim.image_recordings)\n"
    )
    out, _, status = mypy.run(
        [str(script), "--follow-imports=silent", "--cache-dir", str(tmp_path / "cache")]
    )
    assert status == 1 and "Found 1 error" in out, out
    assert 'Revealed type is "acousim.scene.model.Sensor"' in out
    assert 'user.py:8: error: "Sensor" has no attribute "arrray"' in out
    assert 'user.py:13: note: Revealed type is "def (recordings:' in out, out


def test_checked_functions_pickle_by_reference():
    """Worker processes get the same function (the checked one, in its own module)."""
    import pickle

    for fn in (P.doa_spectrum, P.load_recording, acousim.load_scene, hardware.decode):
        assert pickle.loads(pickle.dumps(fn)) is fn


def test_dataclass_fields_keep_their_signature():
    """The keyword check keeps what help() and IDEs show: the real parameters."""
    params = inspect.signature(acousim.Sensor).parameters
    assert "array" in params and "sample_rate_hz" in params
    assert [f.name for f in dataclasses.fields(P.PeakRow)] == list(P.PEAK_COLUMNS)
