"""The Python client's own build backend (PEP 517), standard library only.

Why not setuptools: `pip install ./python` then needs setuptools and wheel inside the build
environment. In a plain venv, offline (a build machine without PyPI), or with
--no-build-isolation in a venv that has setuptools but no wheel, that install failed
("invalid command 'bdist_wheel'"). The package is pure Python with no dependencies, so a wheel
is a zip of its files and three metadata files (PEP 427, core metadata 2.1); this backend
writes exactly that, and pip needs nothing but itself.

pyproject.toml's [project] table is the one source of the name, version and description.
"""
import base64
import hashlib
import io
import os
import re
import tarfile
import zipfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = "springfit_client"


def _project():
    """The [project] fields this backend uses, from pyproject.toml."""
    text = open(os.path.join(ROOT, "pyproject.toml"), encoding="utf-8").read()
    try:
        import tomllib  # Python 3.11 and later

        return tomllib.loads(text)["project"]
    except ImportError:  # 3.9 and 3.10: the table's simple `key = "value"` lines
        table = text.split("[project]", 1)[1].split("\n[", 1)[0]
        return dict(re.findall(r'^([\w-]+)\s*=\s*"([^"]*)"', table, re.M))


def _names():
    project = _project()
    dist = re.sub(r"[-_.]+", "_", project["name"]).lower()
    return project, dist, f"{dist}-{project['version']}"


def _metadata(project):
    lines = [
        "Metadata-Version: 2.1",
        f"Name: {project['name']}",
        f"Version: {project['version']}",
        f"Summary: {project.get('description', '')}",
        f"Requires-Python: {project.get('requires-python', '>=3.9')}",
        "Description-Content-Type: text/markdown",
        "",
        open(os.path.join(ROOT, "README.md"), encoding="utf-8").read(),
    ]
    return "\n".join(lines).encode()


def _package_files():
    """(path in the archive, path on disk) of the package, sorted: the same bytes every time."""
    folder = os.path.join(ROOT, PACKAGE)
    names = sorted(n for n in os.listdir(folder) if n.endswith(".py") or n == "py.typed")
    return [(f"{PACKAGE}/{n}", os.path.join(folder, n)) for n in names]


def _record_line(name, data):
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def _write_zip(archive, name, data):
    info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))  # reproducible
    info.external_attr = 0o644 << 16
    info.compress_type = zipfile.ZIP_DEFLATED
    archive.writestr(info, data)


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    project, dist, base = _names()
    wheel_name = f"{base}-py3-none-any.whl"
    info = f"{base}.dist-info"
    files = [(name, open(path, "rb").read()) for name, path in _package_files()]
    files.append((f"{info}/METADATA", _metadata(project)))
    files.append((f"{info}/WHEEL", b"Wheel-Version: 1.0\nGenerator: springfit_build\n"
                                   b"Root-Is-Purelib: true\nTag: py3-none-any\n"))
    record = [_record_line(name, data) for name, data in files] + [f"{info}/RECORD,,"]
    with zipfile.ZipFile(os.path.join(wheel_directory, wheel_name), "w") as archive:
        for name, data in files:
            _write_zip(archive, name, data)
        _write_zip(archive, f"{info}/RECORD", ("\n".join(record) + "\n").encode())
    return wheel_name


def build_sdist(sdist_directory, config_settings=None):
    project, dist, base = _names()
    sdist_name = f"{base}.tar.gz"
    members = [("pyproject.toml", "pyproject.toml"), ("README.md", "README.md"),
               ("_build/springfit_build.py", "_build/springfit_build.py")]
    members += [(name, os.path.relpath(path, ROOT)) for name, path in _package_files()]
    with tarfile.open(os.path.join(sdist_directory, sdist_name), "w:gz") as archive:
        for name, relative in members:
            data = open(os.path.join(ROOT, relative), "rb").read()
            entry = tarfile.TarInfo(f"{base}/{name}")
            entry.size, entry.mode, entry.mtime = len(data), 0o644, 0
            archive.addfile(entry, io.BytesIO(data))
        pkg_info = _metadata(project)
        entry = tarfile.TarInfo(f"{base}/PKG-INFO")
        entry.size, entry.mode, entry.mtime = len(pkg_info), 0o644, 0
        archive.addfile(entry, io.BytesIO(pkg_info))
    return sdist_name


def get_requires_for_build_wheel(config_settings=None):
    return []


def get_requires_for_build_sdist(config_settings=None):
    return []
