"""blobflow's ParaView plugin (ParaView 5.11 or later): *Tools > Manage Plugins > Load New...*,
``LoadPlugin(PATH, ns=globals())`` in pvpython, or ``PV_PLUGIN_PATH``.

It adds, in the *blobflow* menus, the filter **blobflow Particle Surface** (the surface of any
point set at every time step, with blobflow's surface options in its panel) and one time-aware
source per installed scene, with the scene's parameters in its panel (the scene runs once, in
the background, into ``BLOBFLOW_PARAVIEW_CACHE``, default ``~/.cache/blobflow/paraview``, or
the source's *Folder*; a time step shows as soon as its frame is written).

ParaView runs on its own Python and VTK, so this file imports nothing of blobflow: it runs
``PYTHON -m pipeline.paraview.bridge`` (one worker per session) and ``PYTHON -m pipeline run``
in blobflow's environment and exchanges VTK XML files with them. ``PYTHON`` is, in order:
``BLOBFLOW_PYTHON``; the interpreter of the ``blobflow`` command on ``PATH``; the ``.venv`` of
the source tree this file is in; the interpreter of the environment it is installed in.
"""

import hashlib
import inspect
import json
import math
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

if not hasattr(inspect, "getargspec"):  # Python >= 3.11 under ParaView 5.11: startup.py
    inspect.getargspec = inspect.getfullargspec

from paraview.util.vtkAlgorithm import VTKPythonAlgorithmBase, smdomain, smhint, smproperty, smproxy
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import (
    vtkCompositeDataSet,
    vtkMultiBlockDataSet,
    vtkPointSet,
    vtkPolyData,
)
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline
from vtkmodules.vtkIOXML import (
    vtkXMLPolyDataReader,
    vtkXMLPolyDataWriter,
    vtkXMLUnstructuredGridReader,
)

paraview_plugin_name = "blobflow"
paraview_plugin_version = "1.0"

_SDDP = vtkStreamingDemandDrivenPipeline
#: The surface options shown in the panel and their defaults (blobflow's SURFACE_DEFAULTS; the
#: test suite checks that they agree).
KERNELS = ("sph", "blobby", "metaball", "zhu_bridson")
SURFACE = {"radius": 0.01, "kernel": "sph", "anisotropic": True, "feature_smoothing": 25,
           "smooth_iterations": 30, "pass_band": 0.01, "normals": True,
           "attributes": ("velocity",), "liquid": False, "volume_correction": None}
#: The panel's choices for the volume correction (None: as Liquid).
VOLUME_CORRECTION = ((None, "as Liquid"), (True, "on"), (False, "off"))
#: Environment variables that would make blobflow's Python load ParaView's modules or libraries.
_FOREIGN = ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "LD_LIBRARY_PATH", "LD_PRELOAD",
            "VTK_DEFAULT_OPENGL_WINDOW")


# -- blobflow's environment ------------------------------------------------------------------------
def _shebang(path):
    try:
        with open(path, "rb") as f:
            line = f.readline().decode("utf-8", "replace").strip()
    except OSError:
        return None
    return line[2:].strip().split()[0] if line.startswith("#!") and len(line) > 2 else None


def blobflow_python():
    """The Python of blobflow's environment (see the module docstring), or raise RuntimeError."""
    here = Path(__file__).resolve()
    candidates = [os.environ.get("BLOBFLOW_PYTHON")]
    script = shutil.which("blobflow")
    if script:
        candidates.append(_shebang(script))
    candidates.append(str(here.parents[2] / ".venv" / "bin" / "python"))
    if "site-packages" in here.parts:  # PREFIX/lib/pythonX.Y/site-packages/pipeline/paraview/this
        candidates.append(str(here.parents[5] / "bin" / "python"))
    for candidate in candidates:
        if candidate and os.path.isfile(candidate) and os.access(candidate, os.X_OK):
            return candidate
    raise RuntimeError("blobflow's Python was not found: set BLOBFLOW_PYTHON to the python of "
                       "the environment blobflow is installed in (e.g. .venv/bin/python)")


def _environment():
    env = {k: v for k, v in os.environ.items() if k not in _FOREIGN}
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env


def _run_blobflow(arguments, timeout=None):
    """Run ``PYTHON -m ARGUMENTS`` in blobflow's environment; RuntimeError with its last line."""
    result = subprocess.run([blobflow_python(), "-m", *arguments], capture_output=True,
                            text=True, env=_environment(), timeout=timeout)
    if result.returncode != 0:
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        raise RuntimeError(lines[-1] if lines else f"blobflow exited with {result.returncode}")
    return result.stdout


_BRIDGE = "pipeline.paraview.bridge"  # blobflow's end: `PYTHON -m pipeline.paraview.bridge`
_DESCRIPTION = None
_WORKER = None  # one `python -m pipeline.paraview.bridge serve` per ParaView session


def _worker_request(request):
    """Send one request to blobflow's worker process (started on first use, restarted once
    if it died) and return its answer; RuntimeError with blobflow's message on failure."""
    global _WORKER
    for attempt in (0, 1):
        if _WORKER is None or _WORKER.poll() is not None:
            log = tempfile.TemporaryFile(mode="w+", prefix="blobflow-worker-")
            _WORKER = subprocess.Popen([blobflow_python(), "-m", _BRIDGE, "serve"],
                                       stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                       stderr=log, text=True, env=_environment())
            _WORKER.log = log
        try:
            _WORKER.stdin.write(json.dumps(request) + "\n")
            _WORKER.stdin.flush()
            line = _WORKER.stdout.readline()
        except (BrokenPipeError, OSError):
            line = ""
        if line:
            answer = json.loads(line)
            if not answer.get("ok"):
                raise RuntimeError(answer.get("error", "blobflow failed"))
            return answer
        _WORKER.wait(timeout=30)
        _WORKER.log.seek(0)
        lines = [line for line in _WORKER.log.read().splitlines() if line.strip()]
        if attempt:
            raise RuntimeError(lines[-1] if lines else "blobflow's worker process died")
    return None


def description():
    """blobflow's ``describe`` (scenes and surface options), asked once per session."""
    global _DESCRIPTION
    if _DESCRIPTION is None:
        _DESCRIPTION = json.loads(_run_blobflow([_BRIDGE, "describe"], timeout=300))
    return _DESCRIPTION


# -- VTK files -------------------------------------------------------------------------------------
def _read(path):
    reader = (vtkXMLPolyDataReader if str(path).endswith(".vtp")
              else vtkXMLUnstructuredGridReader)()
    reader.SetFileName(str(path))
    reader.Update()
    data = reader.GetOutputDataObject(0)
    copy = data.NewInstance()
    copy.ShallowCopy(data)
    return copy


def _write_points(data, path):
    """The points and point arrays of any point set as a .vtp file (cells are not needed)."""
    cloud = vtkPolyData()
    points = data.GetPoints()
    cloud.SetPoints(points if points is not None else vtkPoints())
    cloud.GetPointData().ShallowCopy(data.GetPointData())
    writer = vtkXMLPolyDataWriter()
    writer.SetInputData(cloud)
    writer.SetFileName(str(path))
    writer.SetDataModeToAppended()
    writer.EncodeAppendedDataOff()
    if writer.Write() != 1:
        raise RuntimeError(f"could not write {path}")


def _written_elsewhere(folder):
    """Whether a live process holds blobflow's lock on ``folder`` (pipeline/io/folderlock.py):
    another source's run writes there, and its frames will come."""
    try:
        owner = json.loads((Path(folder) / ".blobflow.lock").read_text(encoding="utf-8"))
        if owner.get("host") == socket.gethostname():  # another machine's: cannot be checked
            os.kill(int(owner["pid"]), 0)
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        return isinstance(exc, PermissionError)  # alive, someone else's; else none or dead
    return True


def _collection(path):
    """(time, file) of every frame a .pvd lists so far (it is rewritten after every frame)."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        return []
    return [(float(d.get("timestep")), d.get("file")) for d in root.iter("DataSet")]


# -- The surface filter ----------------------------------------------------------------------------
def _text(value):
    """A string property's value; ParaView passes an empty one as None."""
    return "" if value is None or str(value) == "None" else str(value)


def _documentation(text):
    return smdomain.xml(f"<Documentation>{text}</Documentation>")


@smproxy.filter(name="blobflowParticleSurface", label="blobflow Particle Surface")
@smhint.xml('<ShowInMenu category="blobflow"/>')
@smproperty.input(name="Input", port_index=0)
@smdomain.datatype(dataTypes=["vtkPointSet"], composite_data_supported=True)
class ParticleSurface(VTKPythonAlgorithmBase):
    """Particles -> implicit surface (metaball splat, flying edges, feature and windowed-sinc
    smoothing) by blobflow's ``reconstruct``, at every time step of the input."""

    def __init__(self):
        VTKPythonAlgorithmBase.__init__(self, nInputPorts=1, nOutputPorts=1,
                                        inputType="vtkPointSet", outputType="vtkPolyData")
        self._options = dict(SURFACE)
        self._options["cell_size"] = 0.0
        self._options["radius_array"] = ""

    def _set(self, name, value):
        if self._options.get(name) != value:
            self._options[name] = value
            self.Modified()

    @smproperty.doublevector(name="Radius", default_values=SURFACE["radius"])
    @smdomain.doublerange(min=0.0)
    @_documentation("Particle radius (m), > 0.")
    def SetRadius(self, value):
        self._set("radius", float(value))

    @smproperty.doublevector(name="CellSize", label="Cell Size", default_values=0.0)
    @_documentation("Voxel edge (m); 0 for half the radius.")
    def SetCellSize(self, value):
        self._set("cell_size", float(value))

    @smproperty.intvector(name="Kernel", default_values=KERNELS.index(SURFACE["kernel"]))
    @smdomain.xml('<EnumerationDomain name="enum">' + "".join(
        f'<Entry value="{i}" text="{k}"/>' for i, k in enumerate(KERNELS)) + "</EnumerationDomain>")
    @_documentation("Splatting kernel: sph (cubic spline), blobby, metaball or zhu_bridson.")
    def SetKernel(self, value):
        self._set("kernel", KERNELS[int(value)])

    @smproperty.intvector(name="Anisotropic", default_values=int(SURFACE["anisotropic"]))
    @smdomain.xml('<BooleanDomain name="bool"/>')
    @_documentation("Anisotropic kernels (Yu and Turk 2013): flat water comes out flat "
                    "(sph, blobby and metaball kernels).")
    def SetAnisotropic(self, value):
        self._set("anisotropic", bool(int(value)))

    @smproperty.intvector(name="FeatureSmoothing", label="Feature Smoothing",
                          default_values=SURFACE["feature_smoothing"])
    @smdomain.intrange(min=0, max=10000)
    @_documentation("Sweeps of feature-weighted smoothing (Loeschner et al. 2023); 0 for none.")
    def SetFeatureSmoothing(self, value):
        self._set("feature_smoothing", int(value))

    @smproperty.intvector(name="SmoothIterations", label="Smooth Iterations",
                          default_values=SURFACE["smooth_iterations"])
    @smdomain.intrange(min=0, max=1000)
    @_documentation("Windowed-sinc smoothing iterations (Taubin et al. 1996); 0 for none.")
    def SetSmoothIterations(self, value):
        self._set("smooth_iterations", int(value))

    @smproperty.doublevector(name="PassBand", label="Pass Band",
                             default_values=SURFACE["pass_band"])
    @smdomain.doublerange(min=0.0, max=2.0)
    @_documentation("Windowed-sinc pass band in (0, 2); lower smooths more.")
    def SetPassBand(self, value):
        self._set("pass_band", float(value))

    @smproperty.intvector(name="Liquid", default_values=int(SURFACE["liquid"]))
    @smdomain.xml('<BooleanDomain name="bool"/>')
    @_documentation("The particles are a liquid's, at a spacing of 2 radius (an SPH "
                    "simulation's): volume correction, and the surface is tagged as a liquid's "
                    "(blobflow_kind, drawn as water).")
    def SetLiquid(self, value):
        self._set("liquid", bool(int(value)))

    @smproperty.intvector(name="VolumeCorrection", label="Volume Correction",
                          default_values=[v for v, _ in VOLUME_CORRECTION].index(
                              SURFACE["volume_correction"]))
    @smdomain.xml('<EnumerationDomain name="enum">' + "".join(
        f'<Entry value="{i}" text="{t}"/>' for i, (_, t) in enumerate(VOLUME_CORRECTION))
        + "</EnumerationDomain>")
    @_documentation("Offset every closed piece of the surface along its normals until it "
                    "encloses its particles' volume, (2 radius)^3 each (a liquid's particles); "
                    "by default where Liquid is on.")
    def SetVolumeCorrection(self, value):
        self._set("volume_correction", VOLUME_CORRECTION[int(value)][0])

    @smproperty.intvector(name="Normals", default_values=int(SURFACE["normals"]))
    @smdomain.xml('<BooleanDomain name="bool"/>')
    @_documentation("Compute point normals.")
    def SetNormals(self, value):
        self._set("normals", bool(int(value)))

    @smproperty.stringvector(name="Attributes", default_values=",".join(SURFACE["attributes"]))
    @_documentation("Point arrays of the particles carried to the surface, comma-separated.")
    def SetAttributes(self, value):
        self._set("attributes", tuple(v.strip() for v in _text(value).split(",") if v.strip()))

    @smproperty.stringvector(name="RadiusArray", label="Radius Array", default_values="")
    @_documentation("Point array of per-particle radii (m); empty for one radius.")
    def SetRadiusArray(self, value):
        self._set("radius_array", _text(value))

    def options(self):
        """The options passed to blobflow's reconstruct."""
        options = {k: v for k, v in self._options.items() if k not in ("cell_size",
                                                                         "radius_array")}
        options["attributes"] = list(options["attributes"])
        if self._options["cell_size"] > 0:
            options["cell_size"] = self._options["cell_size"]
        if self._options["radius_array"]:
            options["radius_array"] = self._options["radius_array"]
        return options

    def RequestData(self, request, inInfo, outInfo):
        data = vtkPointSet.GetData(inInfo[0], 0)
        output = vtkPolyData.GetData(outInfo, 0)
        with tempfile.TemporaryDirectory(prefix="blobflow-pv-") as folder:
            source, target = Path(folder) / "particles.vtp", Path(folder) / "surface.vtp"
            _write_points(data, source)
            _worker_request({"command": "surface", "source": str(source),
                             "target": str(target), "options": self.options()})
            output.ShallowCopy(_read(target))
        return 1


# -- Scene sources, one per installed scene --------------------------------------------------------
def frame_times(fps, duration):
    """The frame times of a run, as blobflow computes them (``round(i / fps, 9)``)."""
    count = math.floor(duration * fps + 1e-9) + 1
    return [round(i / fps, 9) for i in range(count)]


def cache_root():
    """Where scene runs go unless a source names its folder."""
    root = os.environ.get("BLOBFLOW_PARAVIEW_CACHE")
    return Path(root) if root else Path.home() / ".cache" / "blobflow" / "paraview"


class SceneSource(VTKPythonAlgorithmBase):
    """A blobflow scene as a temporal source: a multiblock of its outputs (``particles``,
    ``surface``, ...) at the requested time, read from a run that writes them in the background."""

    SCENE = None  # the scene's entry of describe(), set by _scene_source

    def __init__(self):
        VTKPythonAlgorithmBase.__init__(self, nInputPorts=0, nOutputPorts=1,
                                        outputType="vtkMultiBlockDataSet")
        self._values = {p["name"]: p["default"] for p in self.SCENE["parameters"]}
        self._fps = float(self.SCENE["fps"])
        self._duration = float(self.SCENE["duration"])
        self._folder = ""
        self._process = None
        self._process_folder = None

    def _set(self, name, value):
        if self._values.get(name) != value:
            self._values[name] = value
            self.Modified()

    def SetFPS(self, value):
        if float(value) != self._fps:
            self._fps = float(value)
            self.Modified()

    def SetDuration(self, value):
        if float(value) != self._duration:
            self._duration = float(value)
            self.Modified()

    def SetFolder(self, value):
        if _text(value) != self._folder:
            self._folder = _text(value)
            self.Modified()

    def GetTimestepValues(self):
        return frame_times(self._fps, self._duration)

    # -- the run ---------------------------------------------------------------------------
    def _assignments(self):
        out = []
        for p in self.SCENE["parameters"]:
            value = self._values[p["name"]]
            if value == p["default"]:
                continue
            if isinstance(value, bool):
                value = "true" if value else "false"
            elif isinstance(value, (list, tuple)):
                value = ",".join(repr(float(v)) for v in value)
            out += ["--set", f"{p['name']}={value}"]
        return out

    def folder(self):
        """The run's folder: the one set, or one per scene, parameters, fps and duration."""
        if self._folder:
            return Path(self._folder)
        key = json.dumps([self.SCENE["name"], self._assignments(), self._fps, self._duration])
        digest = hashlib.sha1(key.encode()).hexdigest()[:12]
        return cache_root() / f"{self.SCENE['name']}-{digest}"

    def _start(self, folder):
        if self._process is not None and self._process_folder == folder:
            return
        self._stop()
        folder.mkdir(parents=True, exist_ok=True)
        command = [blobflow_python(), "-m", "pipeline", "run", self.SCENE["name"], "--out",
                   str(folder), "--fps", repr(self._fps), "--duration", repr(self._duration),
                   "--no-render", "--quiet", "--resume", *self._assignments()]
        # a log of this source's own: two sources may share a folder
        self._log_path = folder / f"paraview-run.{os.getpid()}-{id(self) & 0xffffff:06x}.log"
        self._log = open(self._log_path, "w", encoding="utf-8")
        self._process = subprocess.Popen(command, stdout=self._log, stderr=subprocess.STDOUT,
                                         env=_environment())
        self._process_folder = folder

    def _stop(self):
        if self._process is not None and self._process.poll() is None:
            self._process.terminate()
            self._process.wait(timeout=30)
        self._process = None

    def __del__(self):
        try:
            self._stop()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass

    def _outputs(self, folder):
        try:
            record = json.loads((folder / "scene.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        return [n for n in record.get("outputs", []) if isinstance(n, str)]

    def _wait_for(self, folder, index, time_limit=24 * 3600):
        """The outputs' frame files at frame ``index``, once every series lists it."""
        start = time.monotonic()
        while True:
            outputs = self._outputs(folder)
            if outputs:
                lists = [_collection(folder / f"{name}.pvd") for name in outputs]
                if all(len(entries) > index for entries in lists):
                    return {name: folder / entries[index][1]
                            for name, entries in zip(outputs, lists, strict=False)}
            if (self._process is None and folder == self._process_folder
                    and not _written_elsewhere(folder)):
                self._start(folder)  # the other writer stopped short of this frame: go on
            if self._process is not None and self._process.poll() is not None:
                code = self._process.returncode
                self._process = None
                if code != 0 and _written_elsewhere(folder):
                    continue  # refused: another source writes this folder; wait for it
                lines = [line for line in self._log_path.read_text(
                    encoding="utf-8", errors="replace").splitlines() if line.strip()]
                if code != 0:
                    raise RuntimeError(lines[-1] if lines else f"blobflow exited with {code}")
                outputs = self._outputs(folder) or []
                lists = [_collection(folder / f"{name}.pvd") for name in outputs]
                if not outputs or not all(len(entries) > index for entries in lists):
                    raise RuntimeError(f"the run in {folder} ended without frame {index}")
                continue
            if time.monotonic() - start > time_limit:
                raise RuntimeError(f"no frame {index} in {folder} after {time_limit} s")
            time.sleep(0.1)

    # -- pipeline ----------------------------------------------------------------------------
    def RequestInformation(self, request, inInfo, outInfo):
        info = outInfo.GetInformationObject(0)
        times = self.GetTimestepValues()
        info.Remove(_SDDP.TIME_STEPS())
        info.Remove(_SDDP.TIME_RANGE())
        for t in times:
            info.Append(_SDDP.TIME_STEPS(), t)
        info.Set(_SDDP.TIME_RANGE(), [times[0], times[-1]], 2)
        return 1

    def RequestData(self, request, inInfo, outInfo):
        info = outInfo.GetInformationObject(0)
        times = self.GetTimestepValues()
        t = info.Get(_SDDP.UPDATE_TIME_STEP()) if info.Has(_SDDP.UPDATE_TIME_STEP()) else times[0]
        index = min(range(len(times)), key=lambda i: abs(times[i] - t))  # the nearest frame
        folder = self.folder()
        entries = [_collection(folder / f"{n}.pvd") for n in (self._outputs(folder) or [])]
        if not entries or not all(len(e) > index for e in entries):
            self._start(folder)  # resumes a run stopped half way; reuses a complete one
        files = self._wait_for(folder, index)
        output = vtkMultiBlockDataSet.GetData(outInfo, 0)
        output.SetNumberOfBlocks(len(files))
        for block, (name, path) in enumerate(files.items()):
            output.SetBlock(block, _read(path))
            output.GetMetaData(block).Set(vtkCompositeDataSet.NAME(), name)
        output.GetInformation().Set(output.DATA_TIME_STEP(), times[index])
        return 1


def _vector_setter(name, converter, size):
    if size == 1:
        def setter(self, value):
            self._set(name, converter(value))
    else:
        def setter(self, *values):
            self._set(name, [converter(v) for v in values])
    return setter


def _scene_property(parameter):
    """A panel property for one scene parameter: (method name, decorated setter)."""
    name, kind, default = parameter["name"], parameter["kind"], parameter["default"]
    label = name.replace("_", " ").title()
    doc = _documentation(parameter["doc"].replace("&", "and").replace("<", "less than ")
                         .replace(">", "more than ") or name)
    method = "Set_" + name
    if kind == "bool":
        setter = _vector_setter(name, lambda v: bool(int(v)), 1)
        decorated = smproperty.intvector(name=name, label=label, default_values=int(default),
                                         command=method)(
            smdomain.xml('<BooleanDomain name="bool"/>')(doc(setter)))
    elif kind == "int":
        decorated = smproperty.intvector(name=name, label=label, default_values=int(default),
                                         command=method)(doc(_vector_setter(name, int, 1)))
    elif kind == "float":
        decorated = smproperty.doublevector(name=name, label=label, default_values=float(default),
                                            command=method)(doc(_vector_setter(name, float, 1)))
    elif kind == "vector":
        decorated = smproperty.doublevector(name=name, label=label, number_of_elements=len(default),
                                            default_values=[float(v) for v in default],
                                            command=method)(
            doc(_vector_setter(name, float, len(default))))
    else:  # str, names
        text = ",".join(default) if isinstance(default, list) else str(default)
        convert = ((lambda v: [s.strip() for s in _text(v).split(",") if s.strip()])
                   if kind == "names" else _text)
        decorated = smproperty.stringvector(name=name, label=label, default_values=text,
                                            command=method)(doc(_vector_setter(name, convert, 1)))
        if kind == "names":
            default = convert(text)
    return method, decorated


def _fresh(func):
    """A new function calling ``func`` (ParaView keeps a property's XML on the function)."""
    if func.__code__.co_argcount == 1:
        def method(self):
            return func(self)
    else:
        def method(self, value):
            return func(self, value)
    method.__name__ = func.__name__
    return method


def _scene_source(name, scene):
    """A source class (decorated for ParaView) for one scene of describe()."""
    scene = dict(scene, name=name)
    namespace = {"SCENE": scene, "__module__": __name__,
                 "__doc__": f"blobflow scene {name}: {scene['description']}."}
    for parameter in scene["parameters"]:
        method, setter = _scene_property(parameter)
        namespace[method] = setter
    namespace["SetFPS"] = smproperty.doublevector(name="FPS", default_values=scene["fps"])(
        _documentation("Frames per second.")(_fresh(SceneSource.SetFPS)))
    namespace["SetDuration"] = smproperty.doublevector(
        name="Duration", default_values=scene["duration"])(
        _documentation("Simulated seconds.")(_fresh(SceneSource.SetDuration)))
    namespace["SetFolder"] = smproperty.stringvector(name="Folder", default_values="")(
        _documentation("Folder of the run (empty: a cache folder per parameter set).")(
            _fresh(SceneSource.SetFolder)))
    namespace["GetTimestepValues"] = smproperty.doublevector(
        name="TimestepValues", information_only="1", si_class="vtkSITimeStepsProperty")(
        _fresh(SceneSource.GetTimestepValues))
    class_name = f"blobflowScene_{name}"
    cls = type(class_name, (SceneSource,), namespace)
    cls = smhint.xml('<ShowInMenu category="blobflow"/>')(cls)
    return smproxy.source(name=class_name, label=f"blobflow {name}")(cls)


def _register_scenes():
    try:
        scenes = description()["scenes"]
    except Exception as exc:  # noqa: BLE001 - the surface filter still works once fixed
        print(f"blobflow plugin: no scene sources ({exc})", file=sys.stderr)
        return
    for name, scene in scenes.items():
        globals()[f"blobflowScene_{name}"] = _scene_source(name, scene)


_register_scenes()
