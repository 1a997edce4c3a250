"""Every public name of the package has a docstring (python/check_docstrings.py)."""

import importlib.util
from pathlib import Path


def _checker():
    path = Path(__file__).resolve().parents[1] / "check_docstrings.py"
    spec = importlib.util.spec_from_file_location("check_docstrings", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_public_name_has_a_docstring():
    missing = _checker().missing()
    assert not missing, "no docstring:\n" + "\n".join(missing)


def test_the_check_finds_missing_docstrings(tmp_path):
    check = _checker()
    check.HERE = tmp_path / "python"
    src = tmp_path / "m.py"
    src.write_text(
        '"""A module."""\n\nclass Public:\n    def method(self):\n        pass\n\n'
        '    def _private(self):\n        pass\n\n\ndef documented():\n    """Yes."""\n'
    )
    assert check._python(src) == ["m.py:3: Public", "m.py:4: Public.method"]
    rs = tmp_path / "b.rs"
    rs.write_text(
        "/// A class.\n#[pyclass]\nstruct A {}\n\n#[pymethods]\nimpl A {\n"
        "    #[getter]\n    fn x(&self) -> u64 {\n        1\n    }\n\n"
        "    /// Documented.\n    fn y(&self) -> u64 {\n        2\n    }\n}\n"
    )
    assert check._rust(rs) == ["b.rs:8: x"]
