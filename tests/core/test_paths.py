"""Where mppf keeps its own files (mppf.core.paths): $MPPF_HOME, else ~/.local/share/mppf; the seal key apart."""

from __future__ import annotations

from pathlib import Path

from mppf.core.paths import data_dir, installed_press_path, seal_key_path


def test_the_data_folder_is_mppf_home_else_the_user_s_share(tmp_path, monkeypatch):
    monkeypatch.setenv("MPPF_HOME", str(tmp_path / "home"))
    assert data_dir() == tmp_path / "home" and installed_press_path() == tmp_path / "home" / "press.toml"
    assert not (tmp_path / "home").exists()  # named, not created
    monkeypatch.delenv("MPPF_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "user"))
    assert data_dir() == tmp_path / "user" / ".local" / "share" / "mppf"
    monkeypatch.setenv("MPPF_HOME", "")  # set but empty: as unset
    assert data_dir() == Path(tmp_path / "user" / ".local" / "share" / "mppf")


def test_the_seal_key_is_mppf_seal_key_else_in_the_data_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("MPPF_HOME", str(tmp_path))
    monkeypatch.setenv("MPPF_SEAL_KEY", str(tmp_path / "keys" / "shop.key"))
    assert seal_key_path() == tmp_path / "keys" / "shop.key"
    monkeypatch.delenv("MPPF_SEAL_KEY")
    assert seal_key_path() == tmp_path / "seal.key"
