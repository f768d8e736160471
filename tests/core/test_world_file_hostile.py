"""Hostile world files (ird_core.worlds.world_file): each is refused with a ValueError naming the
file and the key, within bounded memory, instead of a traceback or an exhausted machine.

The battery's files are built in one folder; one child process loads them all under an address
space limit (``RLIMIT_AS`` 1 GiB: decoding a 9000 x 9000 PNG as the loader once did needs 2 GB,
expanding a billion-laughs document far more), and reports, per file, the exception's type and
message. Each case then asserts on its own report.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path
from typing import Callable

import numpy as np
import pytest
import yaml
from PIL import Image

from ird_core.worlds import file_values, lavaland, world_file
from ird_core.worlds.terrain import TERRAIN_NAMES

ROOT = Path(__file__).resolve().parents[2]
MEMORY_LIMIT = 1 << 30
COLOURS = {0: [139, 90, 43], 1: [60, 154, 60], 2: [255, 212, 0], 3: [224, 32, 27]}
TRAIN = np.array([[0, 0, 0, 0, 2], [0, 1, 1, 0, 0], [0, 1, 1, 1, 0], [0, 0, 0, 0, 0]], dtype=np.int8)
TEST = np.array([[3, 3, 3, 0, 2], [0, 1, 1, 0, 0], [0, 0, 1, 1, 0], [0, 0, 0, 0, 0]], dtype=np.int8)
CHILD = """
import json, resource, sys
resource.setrlimit(resource.RLIMIT_AS, ({limit}, {limit}))
from ird_core.worlds import world_file
out = {{}}
for case, path in json.load(sys.stdin).items():
    try:
        world_file.load_world_file(path)
        out[case] = ["loaded", ""]
    except BaseException as exc:  # the report says which, the test decides
        out[case] = [type(exc).__name__, str(exc)]
print(json.dumps(out))
"""


def base_doc() -> dict:
    return {
        "name": "hostile",
        "terrains": [{"name": TERRAIN_NAMES[t], "colour": COLOURS[t], "true_reward": float(r)}
                     for t, r in zip(range(4), lavaland.TRUE_TERRAIN_REWARD)],
        "features": {"type": "indicator"},
        "proxy": [0.1, -0.2, 1.0, 0.0],
        "training_worlds": [{"image": "train.png", "start": [0, 0], "horizon": 6}],
        "test_world": {"image": "test.png", "start": [1, 0], "horizon": 6},
    }


def png_header(path: Path, width: int, height: int) -> None:
    """A PNG claiming ``width`` x ``height`` RGB pixels, with one compressed row: a few bytes that a
    decoder would expand into the whole image's buffer."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    body = zlib.compress(b"\x00" + b"\x00" * 3 * width)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", body) + chunk(b"IEND", b""))


def laughs(levels: int = 9, width: int = 9) -> str:
    """A YAML flow sequence of anchors, each repeating the previous one ``width`` times: a few
    hundred bytes whose expansion has ``width ** levels`` leaves."""
    items = ["&l0 [" + ", ".join(["lol"] * width) + "]"]
    items += [f"&l{i} [" + ", ".join([f"*l{i - 1}"] * width) + "]" for i in range(1, levels)]
    return "[" + ", ".join(items) + "]"


def write(folder: Path, doc: dict, text_edit: Callable[[str], str] | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    world_file.write_image(TRAIN, COLOURS, folder / "train.png")
    world_file.write_image(TEST, COLOURS, folder / "test.png")
    text = yaml.safe_dump(doc, sort_keys=False)
    path = folder / "world.yaml"
    path.write_text(text_edit(text) if text_edit else text)
    return path


def edited(folder: Path, edit: Callable[[dict, Path], None]) -> Path:
    doc = base_doc()
    folder.mkdir(parents=True, exist_ok=True)
    edit(doc, folder)
    return write(folder, doc)


def replaced(folder: Path, key: str, yaml_value: str) -> Path:
    """The base file with ``key: <yaml_value>`` (``key`` a top-level or ``test_world.`` key)."""
    doc = base_doc()
    marker = "__HOSTILE__"
    if key.startswith("test_world."):
        doc["test_world"][key.split(".", 1)[1]] = marker
    else:
        doc[key] = marker
    return write(folder, doc, lambda text: text.replace(marker, yaml_value))


def _image(name: str, make: Callable[[Path], None], where: str = "training_worlds") -> Callable[[Path], Path]:
    def build(folder: Path) -> Path:
        folder.mkdir(parents=True, exist_ok=True)
        make(folder)
        doc = base_doc()
        world = doc["training_worlds"][0] if where == "training_worlds" else doc["test_world"]
        world["image"] = name
        return write(folder, doc)
    return build


def _set(edit: Callable[[dict], None]) -> Callable[[Path], Path]:
    return lambda folder: edited(folder, lambda doc, _folder: edit(doc))


def _text(folder: Path, name: str, data: bytes) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_bytes(data)
    return folder / name


def _gif(folder: Path) -> None:
    Image.fromarray(np.zeros((4, 5, 3), dtype=np.uint8)).save(folder / "map.gif")


def _truncated(folder: Path) -> None:
    data = (folder / "ok.png").read_bytes() if (folder / "ok.png").exists() else None
    if data is None:
        world_file.write_image(TRAIN, COLOURS, folder / "ok.png")
        data = (folder / "ok.png").read_bytes()
    (folder / "cut.png").write_bytes(data[: len(data) // 2])


def _symlink_out(folder: Path) -> None:
    outside = folder.parent / f"{folder.name}_outside"
    outside.mkdir(exist_ok=True)
    world_file.write_image(TRAIN, COLOURS, outside / "train.png")
    (folder / "link.png").symlink_to(outside / "train.png")


def _sparse(folder: Path) -> None:
    with open(folder / "big.png", "wb") as fh:  # a sparse file: no disk blocks written
        fh.truncate(file_values.MAX_IMAGE_BYTES + 1)


def _wide_map(width: int, height: int, name: str = "wide.png") -> Callable[[Path], None]:
    return lambda folder: Image.fromarray(np.tile(np.array(COLOURS[0], dtype=np.uint8), (height, width, 1))).save(
        folder / name)


def _vectors(d: int) -> Callable[[dict], None]:
    def edit(doc: dict) -> None:
        doc["features"] = {"type": "vectors", "names": [f"f{i}" for i in range(d)]}
        for i, entry in enumerate(doc["terrains"]):
            entry["features"] = [float(i == j) for j in range(d)]
        doc["proxy"] = [0.0] * d
        doc["training_worlds"][0]["image"] = doc["test_world"]["image"] = "wide.png"
        doc["training_worlds"][0]["horizon"] = doc["test_world"]["horizon"] = 1
    return edit


# (case id, builder of the world file in its own folder, texts the message must contain)
CASES: list[tuple[str, Callable[[Path], Path], list[str]]] = [
    # images: the size from the header, before any pixel is decoded
    ("png_20000x20000", _image("huge.png", lambda f: png_header(f / "huge.png", 20000, 20000)),
     ["training_worlds[0].image", "huge.png", "1000 cells per side"]),
    ("png_9000x9000", _image("big.png", lambda f: png_header(f / "big.png", 9000, 9000)),
     ["training_worlds[0].image", "9000x9000", "1000 cells per side"]),
    ("png_2500x2500_test", _image("map.png", lambda f: png_header(f / "map.png", 2500, 2500), "test_world"),
     ["test_world.image", "2500x2500"]),
    ("png_1001x1", _image("row.png", _wide_map(1001, 1, "row.png")), ["training_worlds[0].image", "row.png is 1001x1"]),
    ("image_file_too_big", _image("big.png", _sparse), ["training_worlds[0].image", "more than the limit 33554432"]),
    ("image_gif", _image("map.gif", _gif), ["training_worlds[0].image", "map.gif is not a PNG, PGM or PPM image"]),
    ("image_truncated", _image("cut.png", _truncated), ["training_worlds[0].image", "cannot decode the image",
                                                        "truncated", "cut.png"]),
    # image paths stay inside the world file's folder; only regular files
    ("image_dotdot", _set(lambda d: d["training_worlds"][0].update(image="../../../../etc/passwd")),
     ["training_worlds[0].image", "inside the world file's folder", "../../../../etc/passwd"]),
    ("image_absolute", _set(lambda d: d["test_world"].update(image="/etc/shadow")),
     ["test_world.image", "absolute paths are refused", "/etc/shadow"]),
    ("image_dev_zero", _set(lambda d: d["test_world"].update(image="/dev/zero")),
     ["test_world.image", "absolute paths are refused", "/dev/zero"]),
    ("image_symlink_out", _image("link.png", _symlink_out), ["training_worlds[0].image", "inside the world file's",
                                                            "link.png"]),
    ("image_symlink_dev_zero", _image("zero.png", lambda f: (f / "zero.png").symlink_to("/dev/zero")),
     ["training_worlds[0].image", "resolves to /dev/zero"]),
    ("image_fifo", _image("fifo.png", lambda f: os.mkfifo(f / "fifo.png")),
     ["training_worlds[0].image", "is not a regular file", "fifo.png"]),
    ("image_folder", _image("dir.png", lambda f: (f / "dir.png").mkdir()),
     ["training_worlds[0].image", "is not a regular file", "dir.png"]),
    # YAML: nesting, aliases, duplicate keys
    ("deep_nesting", lambda f: replaced(f, "proxy", "[" * 100_000 + "]" * 100_000),
     ["proxy[0][0]", "nests collections deeper than 16 levels"]),
    ("laughs_proxy", lambda f: replaced(f, "proxy", laughs()), ["proxy[", "expands to more than 1000000 nodes"]),
    ("laughs_start", lambda f: replaced(f, "test_world.start", laughs()), ["test_world.start[", "expands"]),
    ("laughs_name", lambda f: replaced(f, "name", laughs()), ["name[", "expands"]),
    ("laughs_document", lambda f: _text(f, "world.yaml", "".join(
        f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}" if i else "lol"] * 9) + "]\n" for i in range(9)).encode()),
     ["l6[", "expands to more than 1000000 nodes"]),
    ("alias_cycle", lambda f: replaced(f, "proxy", "&p [1, *p]"), ["proxy[1]", "contains it", "*p"]),
    ("duplicate_key", lambda f: write(f, base_doc(), lambda text: text + "proxy: [0, 0, 0, 0]\n"),
     ["proxy: is given twice"]),
    ("huge_integer", lambda f: replaced(f, "test_world.horizon", "0x" + "f" * 100_000),
     ["test_world.horizon", "an integer of 400000 bits"]),
    # the services' limits, at load time
    ("horizon_1e9", _set(lambda d: d["training_worlds"][0].update(horizon=1_000_000_000)),
     ["training_worlds[0].horizon", "in [1, 1000]", "1000000000"]),
    ("plan_work", lambda f: edited(f, lambda d, folder: (_wide_map(500, 100)(folder), _vectors(4)(d),
                                                         d["test_world"].update(horizon=1000))),
     ["test_world.horizon", "1001 x 100 x 500", "max_plan_work"]),
    ("map_values", lambda f: edited(f, lambda d, folder: (_wide_map(1000, 1000)(folder), _vectors(6)(d))),
     ["training_worlds[0].image", "1000 x 1000 x 6", "max_map_values"]),
    ("yaw", _set(lambda d: d.update(origin=[0.0, 0.0, 0.3])), ["origin", "yaw must be 0", "0.3"]),
    ("gaussian_dim", _set(lambda d: d.update(features={"type": "gaussian", "dim": 100_000, "lavaland_seed": 0})),
     ["features.dim", "in [3, 256]", "100000"]),
    ("many_terrains", _set(lambda d: d.update(terrains=[{"name": f"t{i}", "colour": i} for i in range(200)])),
     ["terrains", "1 to 64"]),
    # keys and types
    ("misspelled_horizon", _set(lambda d: d["training_worlds"][0].update(horizn=6)),
     ["training_worlds[0].horizn", "unknown key", "did you mean 'horizon'?"]),
    ("misspelled_proxy", _set(lambda d: d.update(proxyy=[0.0] * 4)), ["proxyy", "did you mean 'proxy'?"]),
    ("name_not_string", _set(lambda d: d.update(name={"a": 1})), ["name", "printable string", "{'a': 1}"]),
    ("name_long", _set(lambda d: d.update(name="x" * 100_000)), ["name", "1 to 64 characters", "characters)"]),
    # not a world file at all
    ("world_is_png", lambda f: _text(f, "world.png", (ROOT / "worlds" / "figure1_train.png").read_bytes()),
     ["(file)", "is a PNG image"]),
    ("world_is_binary", lambda f: _text(f, "world.yaml", bytes(range(256))), ["(file)", "not UTF-8 text"]),
    ("world_too_big", lambda f: _text(f, "world.yaml", b"# padding\n" * 200_000),
     ["(file)", "more than the limit 1048576"]),
    ("world_not_yaml", lambda f: _text(f, "world.yaml", b"name: [unclosed\n"), ["(top level)", "not valid YAML"]),
    ("world_python_tag", lambda f: _text(f, "world.yaml", b"name: !!python/object/apply:os.system [ls]\n"),
     ["(top level)", "could not determine a constructor"]),
]


@pytest.fixture(scope="module")
def battery(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, str, str]]:
    """{case: (world file, exception type, message)}: every case loaded in one memory-limited child."""
    root = tmp_path_factory.mktemp("hostile")
    paths = {case: build(root / case) for case, build, _ in CASES}
    paths["world_is_dev_zero"] = Path("/dev/zero")
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    # the timeout is no speed requirement: a loader that blocks (a FIFO opened for reading waits
    # for a writer) fails the battery instead of stalling the suite
    run = subprocess.run([sys.executable, "-c", CHILD.format(limit=MEMORY_LIMIT)], input=json.dumps(
        {case: str(path) for case, path in paths.items()}), capture_output=True, text=True, env=env, cwd=ROOT,
        timeout=900)
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr
    report = json.loads(run.stdout)
    return {case: (paths[case], *report[case]) for case in paths}


@pytest.mark.parametrize("case, expected", [(case, expected) for case, _, expected in CASES]
                         + [("world_is_dev_zero", ["(file)", "is not a regular file"])],
                         ids=[case for case, _, _ in CASES] + ["world_is_dev_zero"])
def test_hostile_file_is_refused_naming_file_and_key(battery, case: str, expected: list[str]) -> None:
    path, kind, message = battery[case]
    assert kind == "ValueError", (kind, message)
    assert message.startswith(f"{path}: "), message
    rest = message[len(f"{path}: "):]  # the folder is named after the case: look past it
    for text in expected:
        assert text in rest, (text, message)
    assert len(rest) < 1000, message  # values are shown shortened


def test_limits_admit_their_boundary(tmp_path: Path) -> None:
    """A map of MAX_MAP_SIDE cells per side and a horizon of MAX_HORIZON load: the limits refuse
    only what is past them."""
    side = file_values.MAX_MAP_SIDE
    doc = base_doc()
    _wide_map(side, 1)(tmp_path)
    doc["training_worlds"][0].update(image="wide.png", start=[0, 0], horizon=file_values.MAX_HORIZON)
    doc["test_world"].update(image="wide.png", start=[0, side - 1], horizon=file_values.MAX_HORIZON)
    inst = world_file.load_world(write(tmp_path, doc))
    assert inst.test_labels.shape == (1, side) and inst.test_horizon == file_values.MAX_HORIZON


def test_image_symlink_inside_the_folder_and_shared_yaml_nodes_load(tmp_path: Path) -> None:
    """What the checks allow: a symlink that stays in the folder, and YAML aliases that do not
    blow up (PyYAML's safe_dump writes one for a list used twice)."""
    doc = base_doc()
    doc["test_world"]["start"] = doc["training_worlds"][0]["start"] = [0, 0]  # one list: dumped as an alias
    (tmp_path / "maps").mkdir()
    world_file.write_image(TEST, COLOURS, tmp_path / "maps" / "real_test.png")
    path = write(tmp_path, doc)
    (tmp_path / "linked.png").symlink_to(tmp_path / "maps" / "real_test.png")
    text = path.read_text().replace("image: test.png", "image: linked.png")
    assert "*id001" in text
    path.write_text(text)
    wf = world_file.load_world_file(path)
    np.testing.assert_array_equal(wf.instance.test_labels, TEST)
    assert wf.instance.test_start == (0, 0) == wf.instance.train_start


def test_a_start_on_a_terrain_no_training_world_shows_is_a_warning(tmp_path: Path) -> None:
    """The test start on lava, which no training map has: loaded (it is the IRD scenario near
    lava), with a warning naming the key and the terrain; on a seen terrain, no warning."""
    doc = base_doc()
    doc["test_world"]["start"] = [0, 0]  # lava in TEST
    wf = world_file.load_world_file(write(tmp_path, doc))
    (warning,) = wf.warnings
    assert warning.startswith(f"{wf.path}: test_world.start: [0, 0] is on lava") and "no training world" in warning
    doc["test_world"]["start"] = [1, 0]  # dirt
    assert world_file.load_world_file(write(tmp_path, doc)).warnings == ()
    for name in ("figure1", "pot_of_gold", "two_training_worlds"):
        assert world_file.load_world_file(ROOT / "worlds" / f"{name}.yaml").warnings == ()
