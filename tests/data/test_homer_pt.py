import pytest

from globe.data.homer_pt import import_household
from globe.errors import DataError


def test_sample_days_convert_byte_for_byte(homer_root, tmp_path):
    written = import_household(homer_root / "raw_sample" / "HouseholdA", tmp_path / "out")
    assert sorted(p.relative_to(tmp_path / "out").as_posix() for p in written) == ["test/000.csv", "train/000.csv"]
    for rel in ("nodes.csv", "train/000.csv", "test/000.csv"):
        assert (tmp_path / "out" / rel).read_bytes() == (homer_root / "HouseholdA" / rel).read_bytes(), rel


def test_importer_reports_a_folder_without_native_files(tmp_path):
    with pytest.raises(DataError, match="no processed_seqLM_coarse folder"):
        import_household(tmp_path, tmp_path / "out")
