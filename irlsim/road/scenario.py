"""Scenario files: a SUMO network, the ego's route on it and what the network cannot say.

A scenario is a TOML file (``scenario.toml``) in a folder of its own. The shipped ones live under
``sumo_net/<name>/`` (installed with the package); any other is named by its path::

    name = "highway"
    description = "three-lane motorway in Bremen (OpenStreetMap, from SUMO's game)"

    [network]                # exactly one of:
    file = "net.net.xml"     #   a SUMO network (.net.xml or .net.xml.gz), relative to this file or absolute
    # netconvert = "x.cfg"   #   a netconvert configuration (plain node/edge XML), built into a cache
    # osm = "map.osm"        #   an OpenStreetMap extract, built with netconvert into a cache
    # opendrive = "map.xodr" #   an OpenDRIVE map (CARLA's, esmini's), built with netconvert into a cache
    # sumo_tools = "game/highway/highway.net.xml"   # a network inside the installed eclipse-sumo wheel
    additional = ["lights.tll.xml"]   # optional: SUMO additional files it runs with (its signal programs)

    [route]                  # the ego's route: a list of edges, or from/to (the shortest path on the net)
    edges = ["a", "b", "c"]
    # from = "a"
    # to = "c"

    [defaults]               # optional: this road's episode settings (irlsim.sim.config.EpisodeConfig)
    n_vehicles = 8           #   e.g. the traffic, the ego's start; a collect config overrides them

    [traffic]                # optional: the scenario's own SUMO demand instead of irlsim's spawner
    routes = ["demand.rou.xml"]
    warmup = 60.0            # [s] before the ego enters

    [[checkpoints]]          # optional: (x, y) on the route and the lane required there (0 = rightmost)
    x = 250.0
    y = 0.0
    lane = 2

A route whose last edge leads back into its first is a loop (laps); any other route is open and the
episode ends at its end. What the network says (lanes, widths, exits, all-way stops) is derived from it
by :class:`irlsim.road.Road`.
"""

from __future__ import annotations

import functools
import gzip
import hashlib
import os
import shutil
import tomllib
import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from irlsim.config import from_dict
from irlsim.errors import IrlsimError
from irlsim.road.network import SUMO_NET_DIR, build_net, config_sources, is_stale, sumo_home, sumo_tools_path
from irlsim.utils import atomic_path

SCENARIO_FILE = "scenario.toml"
NETWORK_SOURCES = ("file", "netconvert", "osm", "sumo_tools", "netgenerate", "opendrive")
#: the road of a config that names none
DEFAULT_SCENARIO = "oval"


@dataclass(frozen=True)
class NetworkSpec:
    """Where the network comes from: exactly one field set (paths relative to the scenario file)."""

    file: str = ""
    """a SUMO network, .net.xml or .net.xml.gz"""
    netconvert: str = ""
    """a netconvert configuration file (its inputs relative to it); built once into the cache"""
    osm: str = ""
    """an OpenStreetMap extract (.osm / .osm.xml); built once with netconvert into the cache"""
    sumo_tools: str = ""
    """a network inside the installed eclipse-sumo wheel, relative to its ``tools/`` folder"""
    netgenerate: str = ""
    """a netgenerate configuration (a grid, spider or random network); built once into the cache"""
    opendrive: str = ""
    """an OpenDRIVE map (.xodr: CARLA's and esmini's format); built once with netconvert into the cache
    (its driving lanes, as netconvert imports them by default)"""
    additional: tuple[str, ...] = ()
    """SUMO additional files the network runs with, e.g. its traffic lights' programs (``tlLogic``, as a
    SUMO configuration's ``additional-files`` names them), relative to the scenario file; a path starting
    with ``sumo_tools/`` is inside the installed eclipse-sumo wheel's tools folder"""

    def validate(self) -> None:
        given = [k for k in NETWORK_SOURCES if getattr(self, k)]
        if len(given) != 1:
            raise IrlsimError(
                f"scenario: [network] needs exactly one of {', '.join(NETWORK_SOURCES)}; got "
                f"{', '.join(given) or 'none'}"
            )


@dataclass(frozen=True)
class RouteSpec:
    """The ego's route: ``edges`` in order, or ``from`` / ``to`` resolved by the shortest path."""

    edges: tuple[str, ...] = ()
    from_edge: str = ""
    to_edge: str = ""

    def validate(self) -> None:
        if bool(self.edges) == bool(self.from_edge or self.to_edge):
            raise IrlsimError("scenario: [route] needs either edges = [...] or from = ... and to = ...")
        if not self.edges and not (self.from_edge and self.to_edge):
            raise IrlsimError("scenario: [route] needs both from and to")


@dataclass(frozen=True)
class TrafficSpec:
    """The scenario's own SUMO demand instead of irlsim's spawner (which keeps ``n_vehicles`` around the
    ego): route / flow files whose vehicles enter and leave as SUMO drives them."""

    routes: tuple[str, ...] = ()
    """SUMO route files (.rou.xml: vehicles, flows, their types), relative to the scenario file; a path
    starting with ``sumo_tools/`` is inside the installed eclipse-sumo wheel's tools folder"""
    warmup: float = 0.0
    """[s] simulated before the ego enters, so the demand has filled the road"""

    def validate(self) -> None:
        if not 0.0 <= self.warmup <= 3600.0:
            raise IrlsimError(f"scenario: [traffic] warmup must be in [0, 3600] s, got {self.warmup}")


@dataclass(frozen=True)
class CheckpointSpec:
    x: float
    """[m] world x of a point on the route"""
    y: float
    """[m] world y"""
    lane: int
    """lane required when passing it (0 = rightmost), -1 for any lane"""


@dataclass(frozen=True)
class ScenarioFile:
    """The typed content of a ``scenario.toml`` (unknown keys are errors)."""

    network: NetworkSpec
    route: RouteSpec
    name: str = ""
    description: str = ""
    checkpoints: tuple[CheckpointSpec, ...] = ()
    traffic: TrafficSpec = TrafficSpec()
    defaults: dict[str, Any] = field(default_factory=dict)
    """this road's values of the episode settings (``EpisodeConfig`` fields: traffic, the ego's start,
    limits); a collect config's ``[scenario]`` table and ``--set`` override them"""


@dataclass(frozen=True)
class Scenario:
    """A loaded scenario: the network file ready for SUMO and the route's description."""

    name: str
    path: Path  # the scenario.toml
    net_file: Path
    edges: tuple[str, ...]  # as written, or () when from/to
    from_edge: str
    to_edge: str
    checkpoints: tuple[tuple[float, float, int], ...]
    description: str = ""
    demand: tuple[Path, ...] = ()  # the scenario's own route files (empty: irlsim's spawner)
    warmup: float = 0.0  # [s] before the ego enters
    additional: tuple[Path, ...] = ()  # SUMO additional files the network runs with (signal programs)
    defaults: dict[str, Any] = field(default_factory=dict)  # EpisodeConfig values of this road
    network: NetworkSpec | None = None  # where the network comes from (None: a Scenario made by hand)

    def digest(self) -> str:
        """sha256 of the scenario file and its network: what a dataset records of its road."""
        h = hashlib.sha256(self.path.read_bytes())
        h.update(self.net_file.read_bytes())
        for p in self.additional:  # the signal programs it runs with (none: the digest of before)
            h.update(p.read_bytes())
        return "sha256:" + h.hexdigest()


def shipped_scenarios() -> tuple[str, ...]:
    """Names of the scenarios that ship with irlsim (folders of sumo_net/ with a scenario.toml)."""
    return tuple(sorted(p.parent.name for p in SUMO_NET_DIR.glob(f"*/{SCENARIO_FILE}")))


def scenario_path(spec: str | Path) -> Path:
    """The scenario.toml of a shipped name, a folder or a file; one-line error when there is none."""
    text = str(spec)
    if text in shipped_scenarios():
        return SUMO_NET_DIR / text / SCENARIO_FILE
    p = Path(text)
    if p.is_dir():
        p = p / SCENARIO_FILE
    if p.is_file():
        return p
    raise IrlsimError(
        f"scenario '{text}' not found: name a shipped one ({', '.join(shipped_scenarios())}) or the path of "
        f"a {SCENARIO_FILE} (see docs/guide/scenarios.md)"
    )


def scenario_identity(spec: str | Path | Scenario) -> str:
    """What a dataset records of a road: one identity however the scenario is spelled. A shipped scenario
    is its name (``oval``, ``sumo_net/oval``, ``sumo_net/oval/scenario.toml``, relative or absolute, are
    ``oval``); any other scenario file is ``<its name>@<the first 16 hex digits of its digest>`` (the
    scenario file and its network by content: a copy elsewhere is the same road, no path is recorded).
    A loaded :class:`Scenario` is not read again."""
    scn = spec if isinstance(spec, Scenario) else load_scenario(spec, build=False)
    shipped = {(SUMO_NET_DIR / n / SCENARIO_FILE).resolve(): n for n in shipped_scenarios()}
    if scn.path.resolve() in shipped:
        return shipped[scn.path.resolve()]
    scn = load_scenario(scn)  # its network built (when stale): the identity is of its bytes
    net = scn.net_file
    return _identity(
        str(scn.path.resolve()), scn.name, scn.path.stat().st_mtime_ns, str(net), net.stat().st_mtime_ns
    )


@functools.lru_cache(maxsize=32)
def _identity(path: str, name: str, mtime_ns: int, net: str, net_mtime_ns: int) -> str:
    """(cached while the scenario file and its network are unchanged)"""
    h = hashlib.sha256(Path(path).read_bytes())  # as Scenario.digest
    h.update(Path(net).read_bytes())
    return f"{name}@{h.hexdigest()[:16]}"


def recorded_name(name: str) -> str | None:
    """A ``[scenario] name`` as records keep it (a dataset's config and manifest, a drive table): the
    default is left out (None), as a config that names no road, so the records of the default road keep
    the bytes and hashes they had before scenarios existed; any other name as written."""
    return None if name == DEFAULT_SCENARIO else name


def read_scenario_file(path: Path) -> ScenarioFile:
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise IrlsimError(f"scenario {path} cannot be read ({e}): fix the file") from None
    route = data.get("route")
    if isinstance(route, dict):  # 'from' is a Python keyword: the fields are from_edge / to_edge
        route = dict(route)
        for key in ("from", "to"):
            if key in route:
                route[f"{key}_edge"] = route.pop(key)
        data = {**data, "route": route}
    try:
        return from_dict(ScenarioFile, data)
    except IrlsimError as e:
        raise IrlsimError(f"scenario {path}: {str(e).removeprefix('config: ')}") from None
    except TypeError as e:  # a missing required table
        raise IrlsimError(f"scenario {path}: needs [network] and [route] tables ({e})") from None


def load_scenario(
    spec: str | Path | Scenario = DEFAULT_SCENARIO, build: bool = True, force: bool = False
) -> Scenario:
    """Load a scenario by shipped name or path; builds its network into the cache when it is stale (or
    ``force``: a network irlsim makes from the scenario's source is made again). A loaded
    :class:`Scenario` is not read again: only its network is built (``build``)."""
    if isinstance(spec, Scenario):
        if not build or spec.network is None:
            return spec
        return replace(spec, net_file=_network_file(spec.path, spec.network, build, force))
    path = scenario_path(spec)
    sf = read_scenario_file(path)
    net_file = _network_file(path, sf.network, build, force)
    return Scenario(
        name=sf.name or path.parent.name,
        path=path,
        net_file=net_file,
        edges=tuple(sf.route.edges),
        from_edge=sf.route.from_edge,
        to_edge=sf.route.to_edge,
        checkpoints=tuple((c.x, c.y, c.lane) for c in sf.checkpoints),
        demand=tuple(_route_file(path, r) for r in sf.traffic.routes),
        warmup=sf.traffic.warmup,
        additional=tuple(_route_file(path, a, "[network] additional") for a in sf.network.additional),
        defaults=dict(sf.defaults),
        description=sf.description,
        network=sf.network,
    )


class Scenarios:
    """The scenarios of one command, each read from its file once: ``scenarios(spec)`` is the
    :class:`Scenario` of a shipped name or a path (however spelled), loaded the first time it is named,
    its network built the first time it is asked for with ``build``. A command makes one, resolves its
    roads through it (its config's ``[defaults]`` included) and hands the Scenario objects down; it
    pickles, so worker processes receive the roads instead of reading them again."""

    def __init__(self, *known: Scenario) -> None:
        """``known``: scenarios already loaded (their networks as they are), named by their files."""
        self._loaded: dict[Path, tuple[Scenario, bool]] = {}  # by resolved file: (it, network built)
        for scn in known:
            self._loaded[scn.path.resolve()] = (scn, False)

    def __call__(self, spec: str | Path | Scenario, build: bool = True) -> Scenario:
        if isinstance(spec, Scenario):
            return load_scenario(spec, build=build)
        key = scenario_path(spec).resolve()
        scn, built = self._loaded.get(key, (None, False))
        if scn is None:
            scn, built = load_scenario(spec, build=build), build
        elif build and not built:
            scn, built = load_scenario(scn, build=True), True
        self._loaded[key] = (scn, built)
        return scn

    def identity(self, spec: str | Path | Scenario) -> str:
        """:func:`scenario_identity` of a scenario this command names (read once)."""
        return scenario_identity(self(spec, build=False))


def build_command(spec: str | Path | Scenario) -> str:
    """The command that builds a scenario's network, quoted: 'irlsim net' builds the default road's;
    any other is built as it is loaded ('irlsim scenario show <it>')."""
    if isinstance(spec, Scenario):
        default = spec.path.resolve() == (SUMO_NET_DIR / DEFAULT_SCENARIO / SCENARIO_FILE).resolve()
        spec = DEFAULT_SCENARIO if default else spec.path
    if str(spec) == DEFAULT_SCENARIO:
        return "'irlsim net' (or 'make net')"
    return f"'irlsim scenario show {spec}'"


def network_advice(net_file: Path, scenario_file: Path | None) -> str:
    """What fixes a broken network, as it was made: the default scenario's is rebuilt by 'irlsim net
    --force' (the command that builds it); any other network irlsim built or unpacked from the
    scenario's [network] source is built again once deleted; a network file of the scenario is the
    user's to fix; one of the eclipse-sumo wheel comes back with it."""
    try:
        spec = read_scenario_file(scenario_file).network if scenario_file is not None else None
    except IrlsimError:
        spec = None
    if spec is None:
        return "fix or regenerate it"
    assert scenario_file is not None
    where = f"the [network] of {scenario_file}"
    source = _source(scenario_file, spec)
    made = built_path(scenario_file)
    if net_file.resolve() == made.resolve() and made.resolve() != source.resolve():  # irlsim made it
        if scenario_file.resolve() == scenario_path(DEFAULT_SCENARIO).resolve():  # what 'irlsim net' builds
            return "rebuild it with 'irlsim net --force'"
        return f"delete it: it is made again from {source} ({where}); if it recurs, fix that"
    if net_file.resolve() != source.resolve():  # given instead of the scenario's (irlsim sim --net)
        return "fix or regenerate it"
    if spec.sumo_tools:
        return f"it is eclipse-sumo's ({where}): reinstall it ('pip install --force-reinstall eclipse-sumo')"
    return f"fix or regenerate it ({where})"


def _route_file(scenario: Path, name: str, key: str = "[traffic] routes") -> Path:
    """A file a scenario names under ``key`` (a route file, an additional file)."""
    p = sumo_tools_path(name, scenario.parent)
    if not p.is_file():
        what = "route file" if key == "[traffic] routes" else "file"
        raise IrlsimError(f"scenario {scenario}: {what} {p} not found: fix {key}")
    return p


def _source(scenario: Path, spec: NetworkSpec) -> Path:
    """The file a scenario's network is read, unpacked or built from."""
    if spec.sumo_tools:
        return Path(sumo_home()) / "tools" / spec.sumo_tools
    return scenario.parent / (spec.file or spec.netconvert or spec.netgenerate or spec.opendrive or spec.osm)


def _network_file(path: Path, spec: NetworkSpec, build: bool, force: bool = False) -> Path:
    source = _source(path, spec)
    if spec.file or spec.sumo_tools:
        if not source.is_file():
            raise IrlsimError(
                f"scenario {path}: network {source} not found: fix [network] or restore the file"
            )
        return _gunzip_cached(source, path) if source.suffix == ".gz" else source
    tool, what, args, fix = _recipe(source, spec)
    if not source.is_file():
        raise IrlsimError(f"scenario {path}: {what} {source} not found: fix [network] or restore the file")
    target = built_path(path)
    if not build:
        return target
    sources = config_sources(source) if spec.netconvert or spec.netgenerate else (source,)
    return build_net(
        tool, args, target, subject=str(source), fix=fix, sources=sources, cwd=source.parent, force=force
    )


def _recipe(source: Path, spec: NetworkSpec) -> tuple[str, str, list[str], str]:
    """How a scenario's [network] source is built: the SUMO tool, what the source is, the tool's
    arguments (relative to the source's folder, where it runs) and the fix of a failed build."""
    if spec.netconvert:
        return "netconvert", "netconvert configuration", ["-c", source.name], "fix the XML sources"
    if spec.netgenerate:
        what = "netgenerate configuration"
        return "netgenerate", what, ["-c", source.name], f"fix the {what}"
    if spec.opendrive:
        what = "OpenDRIVE map"
        return "netconvert", what, ["--opendrive-files", source.name, "--no-warnings"], f"fix the {what}"
    what = "OpenStreetMap file"
    return "netconvert", what, ["--osm-files", source.name, *OSM_OPTIONS], f"fix the {what}"


def cache_dir(scenario: Path) -> Path:
    """Where the networks irlsim makes for a scenario go (built from its source, or unpacked): beside it
    when that folder is writable, else the user's cache ($IRLSIM_CACHE or ~/.cache/irlsim)."""
    base = scenario.parent
    if os.access(base, os.W_OK):
        return base
    root = Path(os.environ.get("IRLSIM_CACHE") or Path.home() / ".cache" / "irlsim")
    out = root / "scenarios" / hashlib.sha256(str(scenario.resolve()).encode()).hexdigest()[:16]
    out.mkdir(parents=True, exist_ok=True)
    return out


def built_path(scenario: Path) -> Path:
    """The one place of the network irlsim makes for a scenario, in :func:`cache_dir`: named after the
    scenario, by its folder for a ``scenario.toml`` (the oval's: ``sumo_net/oval/oval.net.xml``)."""
    name = scenario.parent.name if scenario.name == SCENARIO_FILE else scenario.stem
    return cache_dir(scenario) / f"{name}.net.xml"


def _gunzip_cached(net: Path, scenario: Path) -> Path:
    """The compressed network unpacked into the cache (again when it is stale); one line naming it when
    it is truncated or not gzip (nothing is left in the cache)."""
    target = built_path(scenario)
    if is_stale(target, (net,)):
        try:
            with atomic_path(target) as tmp, gzip.open(net, "rb") as src, open(tmp, "wb") as dst:
                shutil.copyfileobj(src, dst)
        except (EOFError, gzip.BadGzipFile, zlib.error) as e:
            raise IrlsimError(
                f"scenario {scenario}: network {net} is malformed: not a whole gzip file ({e}); restore it, "
                "or give it uncompressed (.net.xml)"
            ) from None
    return target


#: netconvert options for an OpenStreetMap extract: ramps and signals guessed, roads for cars only
OSM_OPTIONS = (
    "--geometry.remove", "--ramps.guess", "--junctions.join", "--tls.guess-signals", "--tls.discard-simple",
    "--tls.join", "--remove-edges.isolated", "--keep-edges.by-vclass", "passenger", "--no-warnings",
)  # fmt: skip
