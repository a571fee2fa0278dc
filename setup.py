"""Build hook: a wheel carries the browser page's libraries (three.js and the WebXR
emulator iwer, MIT-licensed, with their licences) copied from ``web/node_modules``, so
that an installed pliant serves its page without npm, and the README's examples
(``pliant examples`` copies them out). Everything else is in pyproject.toml."""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

# What the page imports (static/index.html's import map and app.js), per npm package.
VENDORED = {
    "three": ["LICENSE", "build/three.module.js", "build/three.core.js",
              "examples/jsm/controls/OrbitControls.js",
              "examples/jsm/controls/TransformControls.js",
              "examples/jsm/renderers/CSS2DRenderer.js", "examples/jsm/webxr/VRButton.js"],
    "iwer": ["LICENSE", "build/iwer.module.js"],
}


class BuildWithPageLibraries(build_py):
    """build_py, then the page's libraries into pliant/viewer/vendor/."""

    def run(self) -> None:
        super().run()
        source = Path(__file__).resolve().parent / "web" / "node_modules"
        target = Path(self.build_lib) / "pliant" / "viewer" / "vendor"
        missing = [f"{package}/{name}" for package, names in VENDORED.items()
                   for name in names if not (source / package / name).is_file()]
        if missing:  # a development install serves web/node_modules itself
            self.announce(f"pliant: not bundling the page's libraries ({missing[0]} is "
                          "missing: run `npm ci --prefix web` first)", level=3)
            return
        for package, names in VENDORED.items():
            for name in names:
                destination = target / package / name
                destination.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(source / package / name, destination)


class BuildWithExamples(BuildWithPageLibraries):
    """And the README's examples into pliant/examples/ (``pliant examples`` copies them
    out), links copied as the files they point to."""

    def run(self) -> None:
        super().run()
        examples = Path(__file__).resolve().parent / "examples"
        target = Path(self.build_lib) / "pliant" / "examples"
        if examples.is_dir():
            shutil.rmtree(target, ignore_errors=True)
            shutil.copytree(examples, target, symlinks=False,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))


setup(cmdclass={"build_py": BuildWithExamples})
