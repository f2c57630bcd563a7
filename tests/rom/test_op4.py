"""The in-house Nastran OP4 reader and writer (rom.importers.op4).

References independent of the code under test: files written by hand in these tests following the
OUTPUT4 record layout (header, column records, strings with IS = IROW + 65536 (L + 1) or BIGMAT (L + 1, IROW),
end record), in text and as Fortran-framed binary built with ``struct``.
"""

import struct

import numpy as np
import pytest
import scipy.sparse as sp

from rom.importers import ModelImportError, read_op4, write_op4

A = np.array([[4.0, 1.0, 0.0], [1.0, 5.0, 2.0], [0.0, 2.0, 6.0]])


def _head(ncol, nrow, form, name, mtype=2):
    return f"{ncol:8d}{nrow:8d}{form:8d}{mtype:8d}{name:<8s}1P,3E23.16\n"


def _vals(*v):
    return "".join(f"{x:23.16E}" for x in v) + "\n"


def _ints(*v):
    return "".join(f"{x:8d}" for x in v) + "\n"


def test_text_dense_by_hand(tmp_path):
    # Dense columns, NW as numbers of values in the first matrix and as words in the second: both occur.
    text = (_head(3, 3, 6, "KAA") + _ints(1, 1, 2) + _vals(4, 1) + _ints(2, 1, 3) + _vals(1, 5, 2)
            + _ints(3, 2, 2) + _vals(2, 6) + _ints(4, 1, 1) + _vals(1.0)
            + _head(3, 3, 6, "KWORDS") + _ints(1, 1, 4) + _vals(4, 1) + _ints(2, 1, 6) + _vals(1, 5, 2)
            + _ints(3, 2, 4) + _vals(2, 6) + _ints(4, 1, 1) + _vals(1.0))
    p = tmp_path / "dense.op4"
    p.write_text(text)
    m = read_op4(p)
    assert list(m) == ["KAA", "KWORDS"]
    for name in m:
        np.testing.assert_array_equal(m[name].matrix.toarray(), A)
        assert m[name].form == 6 and m[name].storage == "dense"


def test_text_sparse_classic_and_bigmat_by_hand(tmp_path):
    classic = (_head(3, 3, 6, "K1") + _ints(1, 0, 5) + _ints(1 + 65536 * 5) + _vals(4, 1)
               + _ints(2, 0, 7) + _ints(1 + 65536 * 7) + _vals(1, 5, 2)
               + _ints(3, 0, 5) + _ints(2 + 65536 * 5) + _vals(2, 6) + _ints(4, 1, 1) + _vals(1.0))
    bigmat = (_head(3, -3, 6, "K2") + _ints(1, 0, 6) + _ints(5, 1) + _vals(4, 1)
              + _ints(2, 0, 8) + _ints(7, 1) + _vals(1, 5, 2)
              + _ints(3, 0, 6) + _ints(5, 2) + _vals(2, 6) + _ints(4, 1, 1) + _vals(1.0))
    # One column of two strings (rows 1 and 3–4) and an empty column.
    two = (_head(2, 4, 2, "C") + _ints(2, 0, 8) + _ints(1 + 65536 * 3) + _vals(9)
           + _ints(3 + 65536 * 5) + _vals(8, 7) + _ints(3, 1, 1) + _vals(1.0))
    p = tmp_path / "sparse.op4"
    p.write_text(classic + bigmat + two)
    m = read_op4(p)
    np.testing.assert_array_equal(m["K1"].matrix.toarray(), A)
    np.testing.assert_array_equal(m["K2"].matrix.toarray(), A)
    assert (m["K1"].storage, m["K2"].storage) == ("sparse", "bigmat")
    np.testing.assert_array_equal(m["C"].matrix.toarray(), [[0, 9], [0, 0], [0, 8], [0, 7]])
    assert m["C"].form == 2


def _record(payload: bytes, e: str) -> bytes:
    return struct.pack(e + "i", len(payload)) + payload + struct.pack(e + "i", len(payload))


def _binary_by_hand(e: str, mtype: int = 2) -> bytes:
    out = _record(struct.pack(e + "4i", 3, 3, 6, mtype) + b"KAA     ", e)  # dense
    for icol, irow, vals in ((1, 1, (4, 1)), (2, 1, (1, 5, 2)), (3, 2, (2, 6))):
        out += _record(struct.pack(e + "3i", icol, irow, 2 * len(vals)) + struct.pack(e + f"{len(vals)}d", *vals), e)
    out += _record(struct.pack(e + "3id", 4, 1, 2, 1.0), e)
    out += _record(struct.pack(e + "4i", 3, 3, 6, mtype) + b"KS      ", e)  # classic sparse
    for icol, irow, vals in ((1, 1, (4, 1)), (2, 1, (1, 5, 2)), (3, 2, (2, 6))):
        L = 2 * len(vals)
        body = struct.pack(e + "i", irow + 65536 * (L + 1)) + struct.pack(e + f"{len(vals)}d", *vals)
        out += _record(struct.pack(e + "3i", icol, 0, 1 + L) + body, e)
    out += _record(struct.pack(e + "3id", 4, 1, 2, 1.0), e)
    out += _record(struct.pack(e + "4i", 3, -3, 6, mtype) + b"KB      ", e)  # BIGMAT sparse
    for icol, irow, vals in ((1, 1, (4, 1)), (2, 1, (1, 5, 2)), (3, 2, (2, 6))):
        L = 2 * len(vals)
        body = struct.pack(e + "2i", L + 1, irow) + struct.pack(e + f"{len(vals)}d", *vals)
        out += _record(struct.pack(e + "3i", icol, 0, 2 + L) + body, e)
    out += _record(struct.pack(e + "3id", 4, 1, 2, 1.0), e)
    return out


@pytest.mark.parametrize("e", ["<", ">"])
def test_binary_by_hand_both_byte_orders(tmp_path, e):
    p = tmp_path / "m.op4"
    p.write_bytes(_binary_by_hand(e))
    m = read_op4(p)
    assert [(k, v.storage) for k, v in m.items()] == [("KAA", "dense"), ("KS", "sparse"), ("KB", "bigmat")]
    for v in m.values():
        np.testing.assert_array_equal(v.matrix.toarray(), A)


def _matrices():
    rng = np.random.default_rng(3)
    S = sp.random(40, 40, density=0.15, random_state=rng, format="csc")
    S = (S + S.T + 10 * sp.eye(40)).tocsc()
    S.sort_indices()
    # Explicit zeros: stored entries of value 0, part of the structure (the twin's K has some).
    C = S.tocoo()
    i, j = next((i, j) for i, j in zip(C.row, C.col, strict=True) if i != j)
    for r, c in ((i, j), (j, i)):
        S.data[S.indptr[c] + np.searchsorted(S.indices[S.indptr[c]:S.indptr[c + 1]], r)] = 0.0
    assert (S.data == 0).sum() == 2
    R = sp.random(40, 7, density=0.3, random_state=rng, format="csc") * 1e-7
    return {"KAA": S, "PHI": R}


@pytest.mark.parametrize("binary, sparse, endian", [
    (True, True, "<"), (True, False, "<"), (True, True, ">"), (True, False, ">"), (False, True, "<"),
    (False, False, "<"),
])
def test_write_read_round_trip_is_exact(tmp_path, binary, sparse, endian):
    mats = _matrices()
    p = tmp_path / "rt.op4"
    write_op4(p, mats, binary=binary, sparse=sparse, endian=endian)
    back = read_op4(p)
    assert list(back) == ["KAA", "PHI"]
    for name, A0 in mats.items():
        np.testing.assert_array_equal(back[name].matrix.toarray(), A0.toarray())
        assert back[name].storage == ("bigmat" if sparse else "dense")
    assert back["KAA"].form == 6 and back["PHI"].form == 2
    if sparse:  # sparse strings keep explicit zeros: the structure reads back too
        K0 = mats["KAA"].copy()
        K0.sort_indices()
        np.testing.assert_array_equal(back["KAA"].matrix.indices, K0.indices)
        np.testing.assert_array_equal(back["KAA"].matrix.indptr, K0.indptr)
    assert not list(tmp_path.glob(".*tmp"))  # atomic write


@pytest.mark.parametrize("binary", [True, False])
def test_bigmat_beyond_65535_rows(tmp_path, binary):
    A0 = sp.csc_matrix(([1.5, -2.0, 3.25], ([0, 70_000, 70_001], [0, 1, 1])), shape=(70_002, 2))
    p = tmp_path / "big.op4"
    write_op4(p, {"TALL": A0}, binary=binary)
    M = read_op4(p)["TALL"].matrix
    np.testing.assert_array_equal(M.toarray(), A0.toarray())


def test_only_some_names(tmp_path):
    p = tmp_path / "two.op4"
    write_op4(p, _matrices())
    assert list(read_op4(p, ["PHI"])) == ["PHI"]
    with pytest.raises(ModelImportError, match=r"no matrix 'MAA'.*\['KAA', 'PHI'\]"):
        read_op4(p, ["MAA"])


def _one_line(exc_info, *needles):
    msg = str(exc_info.value)
    assert "\n" not in msg
    for n in needles:
        assert n in msg, (n, msg)


@pytest.mark.parametrize("mtype, what", [(1, "real single precision"), (3, "complex single precision"),
                                         (4, "complex double precision")])
def test_other_types_are_refused(tmp_path, mtype, what):
    p = tmp_path / "t.op4"
    p.write_bytes(_binary_by_hand("<", mtype=mtype))
    with pytest.raises(ModelImportError) as exc:
        read_op4(p)
    _one_line(exc, str(p), what, "TYPE 2")
    p.write_text(_head(3, 3, 6, "KAA", mtype=mtype) + _ints(4, 1, 1) + _vals(1.0))
    with pytest.raises(ModelImportError) as exc:
        read_op4(p)
    _one_line(exc, what)


def test_damaged_binary_files_are_refused(tmp_path):
    good = _binary_by_hand("<")
    p = tmp_path / "d.op4"
    p.write_bytes(good[:-6])  # truncated inside the last end record
    with pytest.raises(ModelImportError) as exc:
        read_op4(p)
    _one_line(exc, str(p), "truncated")
    bad = bytearray(good)
    bad[32 + 4 + 8] ^= 0x40  # the first column's NW: its words no longer fill the record
    p.write_bytes(bytes(bad))
    with pytest.raises(ModelImportError) as exc:
        read_op4(p)
    _one_line(exc, "words announced")
    bad = bytearray(good)
    bad[32 + 4 + 12 + 16] ^= 0x01  # the first column's end-of-record marker
    p.write_bytes(bytes(bad))
    with pytest.raises(ModelImportError) as exc:
        read_op4(p)
    _one_line(exc, "does not match its end marker")
    p.write_bytes(struct.pack("<i", 48) + b"\0" * 52)
    with pytest.raises(ModelImportError) as exc:
        read_op4(p)
    _one_line(exc, "64-bit")


def test_damaged_text_files_are_refused(tmp_path):
    p = tmp_path / "t.op4"
    p.write_text(_head(3, 3, 6, "KAA") + _ints(1, 1, 2) + _vals(4, 1))  # no end record
    with pytest.raises(ModelImportError) as exc:
        read_op4(p)
    _one_line(exc, "without its end record")
    p.write_text(_head(3, -3, 6, "KAA") + _ints(1, 0, 6) + _ints(7, 1) + _vals(4, 1) + _ints(4, 1, 1) + _vals(1.0))
    with pytest.raises(ModelImportError) as exc:  # the string announces 3 values, 2 follow
        read_op4(p)
    _one_line(exc, "announces 3 values, 2 follow")
    p.write_text(_head(3, 3, 6, "KAA") + _ints(1, 3, 2) + _vals(4, 1) + _ints(4, 1, 1) + _vals(1.0))
    with pytest.raises(ModelImportError) as exc:  # rows 3..4 of a 3-row matrix
        read_op4(p)
    _one_line(exc, "outside 1..3")
    p.write_text(_head(3, 3, 6, "KAA") + _ints(2, 1, 1) + _vals(1) + _ints(1, 1, 1) + _vals(4) + _ints(4, 1, 1)
                 + _vals(1.0))
    with pytest.raises(ModelImportError) as exc:
        read_op4(p)
    _one_line(exc, "column 1 after column 2")
    p.write_text(_head(3, 3, 6, "KAA") + _ints(1, 1, 1) + " 4.0000000000000000E+0X\n" + _ints(4, 1, 1) + _vals(1.0))
    with pytest.raises(ModelImportError) as exc:
        read_op4(p)
    _one_line(exc, "not a number")


def test_writer_refuses_what_the_format_cannot_hold(tmp_path):
    with pytest.raises(ValueError, match="1..8 ASCII"):
        write_op4(tmp_path / "x.op4", {"TOO_LONG_NAME": sp.eye(2)})
    with pytest.raises(ValueError, match="1e±99"):
        write_op4(tmp_path / "x.op4", {"K": sp.eye(2) * 1e120}, binary=False)
    write_op4(tmp_path / "x.op4", {"K": sp.eye(2) * 1e120})  # binary holds any double
    assert read_op4(tmp_path / "x.op4")["K"].matrix[0, 0] == 1e120
