#!/usr/bin/env bash
# Builds the documentation site into target/site (open target/site/index.html):
# MkDocs with warnings as errors and its links checked, the tutorials executed
# against the Python package built from this checkout, the Python API page
# from the package's docstrings. The venv is target/docs-venv, or
# REEB_DOCS_VENV (CI passes the one its tests use).
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${REEB_DOCS_VENV:-target/docs-venv}"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
pip=("$venv/bin/pip" install -q --disable-pip-version-check)
# The site's tools (ruff formats the API page's signatures), and what the
# tutorials import beside reeb.
"${pip[@]}" mkdocs-jupyter "mkdocstrings[python]" ruff xarray zarr "dask[distributed]"
# The package the notebooks import, from this checkout (cargo reuses what
# target/ already holds).
"${pip[@]}" "./python[examples]"
NO_MKDOCS_2_WARNING=1 "$venv/bin/mkdocs" build --strict
echo "the site: $PWD/target/site/index.html"
