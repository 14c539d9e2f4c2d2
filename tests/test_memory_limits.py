"""The memory limits a run meets, read from files laid out as Linux lays them out (no monkeypatched
result)."""

import pytest

from pinchmatch import memory

GIB = 2**30


@pytest.fixture
def proc(tmp_path, monkeypatch):
    """A fake /proc and /sys/fs/cgroup: the process in ``system.slice/app.service`` of a v2
    hierarchy."""
    (tmp_path / "cgroup" / "system.slice" / "app.service").mkdir(parents=True)
    (tmp_path / "self_cgroup").write_text("0::/system.slice/app.service\n")
    (tmp_path / "meminfo").write_text(f"MemTotal: {32 * GIB // 1024} kB\nMemAvailable: "
                                      f"{20 * GIB // 1024} kB\n")
    (tmp_path / "status").write_text(f"Name: python\nVmSize: {3 * GIB // 1024} kB\nVmRSS: "
                                     f"{1 * GIB // 1024} kB\n")
    monkeypatch.setattr(memory, "PROC_MEMINFO", str(tmp_path / "meminfo"))
    monkeypatch.setattr(memory, "PROC_STATUS", str(tmp_path / "status"))
    monkeypatch.setattr(memory, "PROC_CGROUP", str(tmp_path / "self_cgroup"))
    monkeypatch.setattr(memory, "CGROUP_ROOT", str(tmp_path / "cgroup"))
    monkeypatch.setattr(memory, "address_space_limit", lambda: None)
    return tmp_path / "cgroup"


def _group(folder, limit, current):
    (folder / "memory.max").write_text(f"{limit}\n" if isinstance(limit, int) else "max\n")
    (folder / "memory.current").write_text(f"{current}\n")


def test_the_machines_free_memory_bounds_a_run_without_other_limits(proc):
    _group(proc / "system.slice", "max", 0)
    _group(proc / "system.slice" / "app.service", "max", 0)
    assert memory.memory_headroom() == (20 * GIB, "20.0 GiB free on this machine")


def test_a_limit_on_a_parent_group_bounds_the_run(proc):
    """A slice of 6 GiB holding 5 GiB above a service with no limit of its own: 1 GiB left."""
    _group(proc / "system.slice", 6 * GIB, 5 * GIB)
    _group(proc / "system.slice" / "app.service", "max", 2 * GIB)
    assert memory.cgroup_headroom() == (6 * GIB, 1 * GIB)
    free, which = memory.memory_headroom()
    assert free == 1 * GIB and "control group's 6.0 GiB" in which


def test_the_tightest_group_is_the_one_with_least_free(proc):
    _group(proc / "system.slice", 8 * GIB, 3 * GIB)  # 5 GiB free
    _group(proc / "system.slice" / "app.service", 4 * GIB, 1 * GIB)  # 3 GiB free
    assert memory.cgroup_headroom() == (4 * GIB, 3 * GIB)


def test_the_address_space_left_is_the_limit_less_what_is_mapped_not_what_is_resident(
    proc, monkeypatch):
    """ulimit -v counts mapped memory: 4 GiB less VmSize's 3 GiB leaves 1 GiB (VmRSS's 1 GiB would
    say 3)."""
    monkeypatch.setattr(memory, "address_space_limit", lambda: 4 * GIB)
    free, which = memory.memory_headroom()
    assert free == 1 * GIB and "ulimit -v" in which


def test_an_address_space_already_overdrawn_leaves_nothing(proc, monkeypatch):
    monkeypatch.setattr(memory, "address_space_limit", lambda: 2 * GIB)  # VmSize is 3 GiB
    assert memory.memory_headroom()[0] == 0


def test_the_out_of_memory_line_names_the_limits_that_are_set(proc, monkeypatch):
    _group(proc / "system.slice", 6 * GIB, 5 * GIB)
    _group(proc / "system.slice" / "app.service", "max", 0)
    line = memory.out_of_memory_message()
    assert ("control group 6.0 GiB" in line and "machine 32.0 GiB" in line
            and "ulimit -v" not in line)
    monkeypatch.setattr(memory, "address_space_limit", lambda: 4 * GIB)
    assert "ulimit -v 4.0 GiB" in memory.out_of_memory_message()
