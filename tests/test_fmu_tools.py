"""The car FMUs (FMI 2.0 and 3.0) against an independent checker: ``fmutool -check`` of
fmu-manipulation-toolbox. It validates modelDescription.xml against the standard's XSD schema
("FMU Generic Conformity Checks"), then checks the rules the schema cannot express ("FMU
Semantic Checks": unique names and value references, causality / variability / initial
combinations, start values, <ModelStructure>). Every finding is logged at level ERROR, and
any makes the tool exit with code 7 (its ``ExitCode.CHECK_FAILED``)."""
import re
import zipfile

import pytest

pytest.importorskip("fmu_manipulation_toolbox")

CHECK_FAILED = 7


def fmutool_check(path) -> tuple[int, list[tuple[str, str]]]:
    """``fmutool -check``'s exit code and its whole log, as `export-fmu --check` reads it."""
    from fmu_src.checks import fmutool_log

    return fmutool_log(path)


@pytest.mark.parametrize("version", [2, 3])
def test_fmutool_check_finds_the_fmu_compliant_with_no_semantic_error(car_fmus, version):
    _, built = car_fmus
    code, log = fmutool_check(built[version].path)
    problems = [(level, msg) for level, msg in log if level not in ("DEBUG", "INFO")]
    assert (code, problems) == (0, []), "\n".join(f"{level}: {msg}" for level, msg in log)
    messages = [msg for _, msg in log]
    assert "=> FMU Generic Conformity Checks" in messages and "=> FMU Semantic Checks" in messages  # both ran
    assert f"This FMU seems to be compliant with FMI-{version}.0." in messages
    assert f"No semantic error against the FMI-{version} standard." in messages


@pytest.mark.parametrize("version", [2, 3])
def test_fmutool_check_fails_a_model_description_with_a_duplicated_name(car_fmus, version, tmp_path):
    """The check above can fail: the same FMU with its variable m_b renamed m_v is refused."""
    _, built = car_fmus
    broken = tmp_path / f"broken{version}.fmu"
    with zipfile.ZipFile(built[version].path) as src, zipfile.ZipFile(broken, "w", zipfile.ZIP_DEFLATED) as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                assert data.count(b'name="m_b"') == 1
                data = data.replace(b'name="m_b"', b'name="m_v"')
            dst.writestr(item, data)
    code, log = fmutool_check(broken)
    assert code == CHECK_FAILED
    section = "FMI-2 §2.2.7" if version == 2 else "FMI-3 §2.4"
    errors = [msg for level, msg in log if level == "ERROR"]
    assert errors[:2] == [
        f"Name 'm_v' is used by several variables{' or aliases' if version == 3 else ''} ({section}).",
        f"1 semantic error(s) against the FMI-{version} standard."]
    assert re.fullmatch(r"-check: \d+ error\(s\) found\.", errors[-1])  # it counts its summary line too



def test_the_fmu_check_record_passes_a_good_fmu_and_fails_a_broken_one(car_fmus, tmp_path):
    """`export-fmu --check`'s record: fmpy's validation, fmutool's checks and the same run in
    fmpy and libcosim (FMI 2) agree that the car FMU is sound, with outputs that moved; the
    same FMU with a duplicated variable name fails."""
    from fmu_src.checks import check_fmu

    _, built = car_fmus
    good = check_fmu(built[2].path)
    assert good["verdict"] == "pass" and good["fmutool"]["pass"] and good["fmpy_validate"]["pass"]
    agree = good["fmpy_vs_libcosim"]
    assert agree["pass"] and agree["worst"] <= 1e-9 and min(agree["std"].values()) > 0
    assert {"z_rail_1", "dz_rail_4"} <= set(agree["inputs"]) and "speed" not in agree["inputs"]
    assert {v["name"]: v["unit"] for v in good["variables"]}["carbody_acc_z"] == "m/s2"
    fmi3 = check_fmu(built[3].path)  # libcosim loads FMI 1 and 2 only: the record says so
    assert "fmpy_vs_libcosim" not in fmi3 and "FMI 3" in fmi3["fmpy_vs_libcosim_not_run"]
    broken = tmp_path / "broken.fmu"
    with zipfile.ZipFile(built[2].path) as src, zipfile.ZipFile(broken, "w", zipfile.ZIP_DEFLATED) as dst:
        for item in src.infolist():
            data = src.read(item)
            dst.writestr(item, data.replace(b'name="m_b"', b'name="m_v"') if item.filename == "modelDescription.xml"
                         else data)
    bad = check_fmu(broken)
    assert bad["verdict"] == "fail" and not bad["fmutool"]["pass"]
    assert any("used by several variables" in p for p in bad["fmutool"]["problems"])
