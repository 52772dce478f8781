"""Load blobflow's ParaView plugin: ``paraview --script=THIS_FILE``, or in pvpython / pvbatch
``exec(open("THIS_FILE").read())``, from any working folder.

Debian's ParaView 5.11 runs on Python 3.11, from which ``inspect.getargspec`` was removed, and
its Python-plugin loader (``paraview.detail.pythonalgorithm``) still imports it, so *every*
Python plugin fails to load there ("Failed to import paraview.detail.pythonalgorithm"). This
script puts back the one thing the loader uses (``getargspec(f).args``, which
``inspect.getfullargspec`` provides) when it is missing, then loads ``plugin.py`` from
this file's folder into the caller's namespace (``blobflowParticleSurface``,
``blobflowdam_break``, ...) and prints one line saying so.

Code run by ``exec`` does not know its file (``__file__`` is the caller's), nor does a script
that ``paraview --script`` runs, so this file finds its folder from, in order:
``BLOBFLOW_PARAVIEW_PLUGIN`` (the plugin's path; ``blobflow paraview --launch`` sets it); the
file it was compiled from (``pvpython THIS_FILE``); the ``exec(open("...paraview/startup.py")
...)`` line of the script that runs it; ParaView's command line (``--script=...``); the last
line typed at an interactive prompt; and last blobflow's Python (``BLOBFLOW_PYTHON``, else the
``blobflow`` command's), asked where its ``pipeline`` package is. ``BLOBFLOW_PARAVIEW_OPEN``
(a JSON list of paths, set by ``blobflow paraview --launch FILE ...``) names data files to open
once the plugin is loaded: ParaView 5.11 refuses data files beside ``--script``. Never imported
by blobflow; ``blobflow paraview`` prints its path.
"""

import inspect as _blobflow_inspect

if not hasattr(_blobflow_inspect, "getargspec"):
    _blobflow_inspect.getargspec = _blobflow_inspect.getfullargspec


def _blobflow_plugin_path():
    """The path of ``plugin.py`` (see the module docstring), or raise RuntimeError."""
    import json
    import linecache
    import os
    import re
    import shutil
    import subprocess
    import sys

    startup, plugin = "startup.py", "plugin.py"
    literal = re.compile(r"""(['"])([^'"]*""" + re.escape(os.path.join("paraview", startup))
                         + r")\1")

    def beside(path):
        if not path:
            return None
        path = os.path.abspath(os.path.expanduser(str(path)))
        folder = os.path.dirname(path)
        if (os.path.basename(path) == startup and os.path.basename(folder) == "paraview"
                and os.path.isfile(path) and os.path.isfile(os.path.join(folder, "bridge.py"))):
            candidate = os.path.join(folder, plugin)
            return candidate if os.path.isfile(candidate) else None
        return None

    def from_lines(lines):
        for line in lines:
            for match in literal.finditer(line or ""):
                found = beside(match.group(2))
                if found:
                    return found
        return None

    def from_frames():
        frame = sys._getframe(3)  # above this, _blobflow_load and this file's own code
        while frame is not None:
            name = frame.f_code.co_filename
            if name and not name.startswith("<"):
                lines = linecache.getlines(name, frame.f_globals)
                at = frame.f_lineno - 1  # the line running this file, then its statement's
                found = from_lines(lines[at:at + 1] + lines[max(at - 3, 0):at + 4])
                if found:
                    return found
            frame = frame.f_back
        return None

    def from_command_line():
        arguments = list(getattr(sys, "orig_argv", None) or []) + list(sys.argv or [])
        try:
            with open("/proc/self/cmdline", "rb") as f:
                arguments += f.read().decode("utf-8", "replace").split("\0")
        except OSError:
            pass
        for argument in arguments:
            found = beside(argument.split("=", 1)[-1])
            if found:
                return found
        return None

    def from_prompt():
        try:
            import readline
        except ImportError:
            return None
        last = readline.get_current_history_length()
        return from_lines(readline.get_history_item(i) for i in range(last, max(last - 5, 0), -1))

    def from_blobflow():
        python = os.environ.get("BLOBFLOW_PYTHON")
        script = shutil.which("blobflow")
        if not python and script:
            with open(script, "rb") as f:
                line = f.readline().decode("utf-8", "replace").strip()
            python = line[2:].strip().split()[0] if line.startswith("#!") else None
        if not python:
            return None
        env = {k: v for k, v in os.environ.items()
               if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "LD_LIBRARY_PATH",
                            "LD_PRELOAD")}
        code = ("import importlib.util, json; s = importlib.util.find_spec('pipeline'); "
                "print(json.dumps(list(s.submodule_search_locations or [])))")
        try:
            result = subprocess.run([python, "-c", code], capture_output=True, text=True,
                                    env=env, timeout=60)
            folders = json.loads(result.stdout) if result.returncode == 0 else []
        except (OSError, ValueError, subprocess.SubprocessError):
            return None
        return next((beside(os.path.join(d, "paraview", startup)) for d in folders
                     if beside(os.path.join(d, "paraview", startup))), None)

    explicit = os.environ.get("BLOBFLOW_PARAVIEW_PLUGIN")
    if explicit:
        if not os.path.isfile(explicit):
            raise RuntimeError(f"BLOBFLOW_PARAVIEW_PLUGIN names no file: {explicit}")
        return os.path.abspath(explicit)
    here = _blobflow_plugin_path.__code__.co_filename  # a real path when run as a file  # noqa: F821 (bound above; ruff sees the del below)
    found = (beside(here) or beside(globals().get("__file__")) or from_frames()
             or from_command_line() or from_prompt() or from_blobflow())
    if found is None:
        raise RuntimeError(
            "blobflow: cannot tell where pipeline/paraview/startup.py is (exec'd at a prompt?): "
            "set BLOBFLOW_PYTHON to the python of blobflow's environment, or run "
            "`pvpython PATH/pipeline/paraview/startup.py`")
    return found


def _blobflow_load(namespace):
    """Load the plugin into ``namespace``, print one line, open BLOBFLOW_PARAVIEW_OPEN."""
    import json
    import os

    from paraview.simple import LoadPlugin

    path = _blobflow_plugin_path()  # noqa: F821 (bound above; ruff sees the del below)
    LoadPlugin(path, ns=namespace)
    scenes = [n for n in namespace if n.startswith("blobflow") and n != "blobflowParticleSurface"]
    print(f"blobflow: loaded the ParaView plugin {path} (filter blobflowParticleSurface, "
          f"{len(scenes)} scene sources)", flush=True)
    files = json.loads(os.environ.pop("BLOBFLOW_PARAVIEW_OPEN", "[]") or "[]")
    if files:
        from paraview.simple import OpenDataFile, Render, Show

        for name in files:
            reader = OpenDataFile(name)
            if reader is None:
                print(f"blobflow: ParaView has no reader for {name}", flush=True)
                continue
            Show(reader)
            print(f"blobflow: opened {name}", flush=True)
        Render()


_blobflow_load(globals())
del _blobflow_load, _blobflow_plugin_path, _blobflow_inspect
