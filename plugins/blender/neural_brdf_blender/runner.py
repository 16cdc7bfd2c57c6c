# SPDX-License-Identifier: MIT
"""Finding and running `render`: the binary, the codes of a latent file (`render codes FILE`)
and a render as a subprocess whose progress (`--progress-lines`) is read as it goes.

Errors are `RenderError`s holding one line for Blender's report: `render`'s own message
(its `error: ...` line without the prefix) or what went wrong starting it.
"""

import os
import queue
import shutil
import signal
import subprocess
import threading

import bpy


class RenderError(Exception):
    """An expected failure, with a one-line message for the user."""


class Cancelled(RenderError):
    """The user pressed Esc."""


def render_binary(settings):
    """The `render` program of `scene.neural_brdf` (its `render_path`, else `render` on PATH)."""
    if settings.render_path.strip():
        path = bpy.path.abspath(settings.render_path.strip())
        if not os.path.isfile(path):
            raise RenderError(f"{path}: no such file (Render Properties > Neural BRDF > Render Binary)")
        if not os.access(path, os.X_OK):
            raise RenderError(f"{path}: not executable (Render Properties > Neural BRDF > Render Binary)")
        return path
    found = shutil.which("render")
    if found is None:
        raise RenderError(
            "the `render` program is not on PATH: set Render Properties > Neural BRDF > Render Binary "
            "(build it with `cargo build --release -p render-cli`: target/release/render)"
        )
    return found


def latent_path(settings):
    """The absolute path of the latent file, or None when none is set."""
    text = settings.latent_file.strip()
    return bpy.path.abspath(text) if text else None


def one_line(stderr_lines, returncode):
    """`render`'s error message: its last `error:` line without the prefix, else its last line."""
    lines = [line.strip() for line in stderr_lines if line.strip()]
    errors = [line for line in lines if line.startswith("error:")]
    if errors:
        return errors[-1][len("error:"):].strip()
    if lines:
        return lines[-1]
    if returncode is not None and returncode < 0:
        return f"render was killed by signal {-returncode}"
    return f"render exited with code {returncode}"


# (binary, latent path, its mtime and size) -> (codes, error message or None)
_codes_cache = {}


def latent_codes(settings):
    """The codes of the scene's latent file as `render codes` lists them, and an error message
    (or None). Cached until the file or the binary changes; no file set: no codes."""
    path = latent_path(settings)
    if path is None:
        return [], None
    try:
        binary = render_binary(settings)
        stat = os.stat(path)
    except RenderError as e:
        return [], str(e)
    except OSError as e:
        return [], f"{path}: {e.strerror}"
    key = (binary, path, stat.st_mtime_ns, stat.st_size)
    if key not in _codes_cache:
        try:
            out = subprocess.run([binary, "codes", path], capture_output=True, text=True, timeout=60)
        except (OSError, subprocess.TimeoutExpired) as e:
            return [], f"{binary}: {e}"
        if out.returncode == 0:
            _codes_cache[key] = ([line.strip() for line in out.stdout.splitlines() if line.strip()], None)
        else:
            _codes_cache[key] = ([], one_line(out.stderr.splitlines(), out.returncode))
    return _codes_cache[key]


class RenderProcess:
    """`render ... --progress-lines` running: `poll` hands over its progress, `stderr` keeps
    its other lines."""

    def __init__(self, argv):
        self.argv = argv
        self.stderr = []
        self.done = False  # stderr closed: the process has ended
        self._lines = queue.Queue()
        try:
            self.process = subprocess.Popen(
                argv,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                text=True,
                errors="replace",
            )
        except OSError as e:
            raise RenderError(f"cannot run {argv[0]}: {e.strerror or e}") from None
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        for line in self.process.stderr:
            self._lines.put(line.rstrip("\n"))
        self._lines.put(None)

    def poll(self, timeout):
        """Waits up to `timeout` seconds for stderr; returns the latest fraction done that
        came (None if none did). Sets `done` at the end of stderr."""
        progress = None
        try:
            line = self._lines.get(timeout=timeout)
            while True:
                if line is None:
                    self.done = True
                elif line.startswith("progress "):
                    try:
                        progress = float(line.split()[1])
                    except (IndexError, ValueError):
                        self.stderr.append(line)
                else:
                    self.stderr.append(line)
                line = self._lines.get_nowait()
        except queue.Empty:
            pass
        return progress

    def stop(self, grace_seconds=10.0):
        """Stops the render as Ctrl-C does (it writes the image rendered so far), killing it
        after `grace_seconds`; returns the exit code."""
        if self.process.poll() is None:
            try:
                if os.name == "posix":
                    self.process.send_signal(signal.SIGINT)
                else:
                    self.process.terminate()
                self.process.wait(timeout=grace_seconds)
            except subprocess.TimeoutExpired:
                self.process.kill()
        return self.finish()

    def finish(self):
        """Waits for the end and collects the rest of stderr; returns the exit code."""
        code = self.process.wait()
        self._reader.join(timeout=5.0)
        while not self.done and not self._lines.empty():
            self.poll(0.0)
        return code
