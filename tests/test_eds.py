"""The drive's EDS (hil_sim/drive/drive.eds) is a well-formed CiA 306 file that describes the
objects the drive keeps (hil_sim/drive/objects.py): canopen's parser accepts files that break
CiA 306's bookkeeping, so the counts are checked here, on the text (cheap: no drive runs)."""

from __future__ import annotations

import configparser
import re

import canopen

from hil_sim.drive import EDS_PATH
from hil_sim.drive.objects import PROCESS_OBJECTS

LISTS = ("MandatoryObjects", "OptionalObjects", "ManufacturerObjects")


def _eds() -> configparser.ConfigParser:
    parser = configparser.ConfigParser(interpolation=None)
    parser.optionxform = str
    parser.read(EDS_PATH)
    return parser


def test_every_object_is_listed_once_and_every_list_counts_its_entries():
    """CiA 306 4.6.2: each object list holds SupportedObjects entries numbered 1..n, and the
    object sections are exactly the listed indices."""
    eds = _eds()
    listed = []
    for name in LISTS:
        section = eds[name]
        count = int(section["SupportedObjects"], 0)
        numbers = sorted(int(key) for key in section if key != "SupportedObjects")
        assert numbers == list(range(1, count + 1)), name
        listed += [int(section[str(n)], 0) for n in numbers]
    sections = {int(name, 16) for name in eds.sections() if re.fullmatch(r"[0-9A-Fa-f]{4}", name)}
    assert len(listed) == len(set(listed)) and set(listed) == sections


def test_every_array_and_record_counts_its_sub_indices():
    """SubNumber is the number of sub-index sections, and sub-index 0 (highest sub-index
    supported) is the last one's number (0x2001: 0x0C, 0x60A4 profile jerk: 1), except where
    CiA 301 makes it a count (0x1003 error field, 0x1600../0x1A00.. PDO mappings: the number of
    entries in use)."""
    eds = _eds()
    for name in eds.sections():
        if not re.fullmatch(r"[0-9A-Fa-f]{4}", name) or "SubNumber" not in eds[name]:
            continue
        subs = sorted(int(s[len(name) + 3:], 16) for s in eds.sections() if s.startswith(name + "sub"))
        assert int(eds[name]["SubNumber"], 0) == len(subs), name
        assert subs[0] == 0, name
        index = int(name, 16)
        if index != 0x1003 and not 0x1600 <= index <= 0x17FF and not 0x1A00 <= index <= 0x1BFF:
            assert int(eds[f"{name}sub0"]["DefaultValue"], 0) == subs[-1], name


def test_the_objects_the_drive_keeps_are_in_the_eds_with_their_types():
    """Every live object of the drive is in the EDS; issue 23's cam objects with the types
    docs/cam_changes.md states (INTEGER64 0x15, INTEGER32 0x04, UNSIGNED32 0x07)."""
    od = canopen.import_od(str(EDS_PATH), 1)
    for key in PROCESS_OBJECTS:
        assert key.index in od, key
        obj = od[key.index]
        if isinstance(obj, canopen.objectdictionary.ODVariable):
            assert key.subindex == 0, key
        else:
            assert key.subindex in obj, key
    types = {(0x2001, 6): 0x15, (0x2001, 7): 0x15, (0x2001, 8): 0x04, (0x2001, 9): 0x07, (0x2001, 10): 0x07,
             (0x2001, 11): 0x07, (0x2001, 12): 0x07, (0x6083, 0): 0x07, (0x6084, 0): 0x07, (0x60A4, 1): 0x07}
    for (index, subindex), data_type in types.items():
        obj = od[index] if subindex == 0 else od[index][subindex]
        assert obj.data_type == data_type, hex(index)
