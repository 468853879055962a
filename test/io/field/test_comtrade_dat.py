"""The chunked COMTRADE data reader gives what the ``comtrade`` package gives, value for value."""

from __future__ import annotations

import numpy as np
import pytest

from phid_ros.io.field.comtrade_dat import ComtradeImportError, open_recording, read_samples
from test.io.field.comtrade_writer import write_comtrade

pytestmark = pytest.mark.usefixtures("comtrade_available")


@pytest.fixture
def comtrade_available() -> None:
    pytest.importorskip("comtrade")


def _channels(n: int) -> dict[str, tuple[np.ndarray, str]]:
    rng = np.random.default_rng(1)
    return {f"CH{k}": (rng.normal(0, 10.0**k, n), "V") for k in range(4)}


def _package(path):
    import comtrade

    rec = comtrade.Comtrade(ignore_warnings=True)
    rec.load(str(path))
    return rec


@pytest.mark.parametrize("ft", ["ASCII", "BINARY"])
@pytest.mark.parametrize("suffix", [".cfg", ".cff"])
@pytest.mark.parametrize("rev", ["1999", "2013"])
def test_chunks_read_the_values_the_package_reads(tmp_path, ft, suffix, rev) -> None:
    path = write_comtrade(tmp_path / f"rec{suffix}", _channels(1003), 1000.0, ft=ft, rev=rev, pad=3 * (ft != "ASCII"))
    cfg, section = open_recording(path)
    samples = read_samples(cfg, section, [1, 3], chunk_rows=7)  # chunks that do not divide the rows
    rec = _package(path)
    assert len(samples) == 1003 and set(samples.stored) == {1, 3}
    for i in (1, 3):
        # the package keeps float32; the same float64 value before its rounding
        assert np.array_equal(samples.values(i).astype(np.float32), np.asarray(rec.analog[i])), i
    assert samples.stored[1].dtype == (np.int16 if ft == "BINARY" else np.float64)
    assert np.array_equal(samples.stamps, np.round(np.arange(1003) * 1e3))


def test_wider_binary_types_and_missing_values(tmp_path) -> None:
    """BINARY32 and FLOAT32 records written by hand; C37.111's missing codes come out NaN."""
    path = write_comtrade(tmp_path / "rec.cfg", _channels(50), 1000.0, ft="BINARY")
    cfg_text = path.read_bytes().decode()
    for ft, stored in (("BINARY32", "<i4"), ("FLOAT32", "<f4")):
        path.write_text(cfg_text.replace("\r\nBINARY\r\n", f"\r\n{ft}\r\n"), newline="")
        raw = np.arange(200, dtype=stored).reshape(50, 4) * 3
        if ft == "BINARY32":
            raw[10, 2] = -(2**31)
        rows = np.zeros(50, dtype=[("n", "<u4"), ("t", "<u4"), ("a", stored, (4,))])
        rows["n"], rows["t"], rows["a"] = np.arange(1, 51), np.arange(50) * 1000, raw
        path.with_suffix(".dat").write_bytes(rows.tobytes())
        cfg, section = open_recording(path)
        samples = read_samples(cfg, section, [2], chunk_rows=16)
        a = float(cfg.analog_channels[2].a)
        expect = raw[:, 2].astype(np.float64) * a
        if ft == "BINARY32":
            expect[10] = np.nan
        assert np.array_equal(samples.values(2), expect, equal_nan=True), ft
        theirs = np.asarray(_package(path).analog[2])
        assert np.array_equal(samples.values(2).astype(np.float32), theirs, equal_nan=True), ft
    # BINARY: -32768 is missing; ASCII 1999: 99999 is missing, a blank stamp is non-critical
    path = write_comtrade(tmp_path / "b.cfg", _channels(20), 1000.0, ft="ASCII")
    dat = path.with_suffix(".dat")
    lines = dat.read_text().splitlines()
    fields = lines[4].split(",")
    fields[1], fields[3] = "", "99999"
    lines[4] = ",".join(fields)
    dat.write_text("\r\n".join(lines) + "\r\n")
    samples = read_samples(*open_recording(path), [0, 1], chunk_rows=6)
    assert np.isnan(samples.stamps[4]) and np.isnan(samples.values(1)[4]) and np.isfinite(samples.values(0)).all()


def test_malformed_data_are_named(tmp_path) -> None:
    path = write_comtrade(tmp_path / "rec.cfg", _channels(40), 1000.0, ft="BINARY")
    dat = path.with_suffix(".dat")
    dat.write_bytes(dat.read_bytes()[:-5])  # the last record cut short
    with pytest.raises(ComtradeImportError, match=r"rec\.dat: 635 bytes is not a whole number of 16-byte records"):
        read_samples(*open_recording(path), [0])
    path = write_comtrade(tmp_path / "a.cfg", _channels(40), 1000.0, ft="ASCII")
    dat = path.with_suffix(".dat")
    lines = dat.read_text().splitlines()
    lines[33] += ",7"
    dat.write_text("\n".join(lines) + "\n")
    with pytest.raises(ComtradeImportError, match=r"a\.dat: rows carry \[6, 7\] values but a\.cfg declares 4 analog"):
        read_samples(*open_recording(path), [0], chunk_rows=64)
    lines[33] = lines[33][:-2].replace(lines[33].split(",")[2], "1.2.3")
    dat.write_text("\n".join(lines) + "\n")
    with pytest.raises(ComtradeImportError, match=r"a\.dat: data row 34, value 3 is '1\.2\.3', not a number"):
        read_samples(*open_recording(path), [0], chunk_rows=8)
    with pytest.raises(ComtradeImportError, match=r"nothing\.cfg: No such file"):
        open_recording(tmp_path / "nothing.cfg")
