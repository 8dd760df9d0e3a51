"""The compiled-library cache is the user's own: created owner-only under the user's cache folder, and a folder or a
library that another user could have planted is refused before anything is loaded; there is no shared fallback."""

import os
import stat

import pytest

from torchpaml import ConfigurationError
from torchpaml._symbolic.compiler import cache_folder, cached_library, compiler

pytestmark = pytest.mark.skipif(compiler() is None, reason="compiling needs a C compiler (cc, gcc) on PATH")

SOURCE = "int answer(void) { return 42; }\n"


def test_the_cache_is_created_owner_only_under_the_users_cache_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    folder = cache_folder()
    assert folder == tmp_path / "cache" / "torchpaml" / "compiled"
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700 and folder.stat().st_uid == os.getuid()
    library = cached_library(SOURCE, "answer", "a test")
    assert library.parent == folder and cached_library(SOURCE, "answer", "a test") == library


def test_a_folder_or_library_others_can_write_is_refused_before_loading(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    library = cached_library(SOURCE, "answer", "a test")
    library.chmod(0o666)  # a planted library would be writable by whoever planted it
    with pytest.raises(ConfigurationError, match=r"the compiled library .* others can write to it"):
        cached_library(SOURCE, "answer", "a test")
    library.chmod(0o644)
    cache_folder().chmod(0o777)
    with pytest.raises(ConfigurationError, match=r"the compiled-library cache .* others can write to it.*XDG_CACHE_HOME"):
        cached_library(SOURCE, "answer", "a test")


def test_a_cache_that_cannot_be_created_is_refused_with_no_shared_fallback(tmp_path, monkeypatch):
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocked))
    with pytest.raises(ConfigurationError, match=r"cannot be created.*XDG_CACHE_HOME"):
        cache_folder()
