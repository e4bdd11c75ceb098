#!/usr/bin/python3
"""Prints the RTU frames the golden-frame test expects, built by pymodbus (an independent
Modbus stack: its own PDU encoding and CRC). Run with Debian's /usr/bin/python3 and paste the
output into profile_golden_test.cc when a profile's commands change on purpose.

Each line: <profile> <command> <slave> <hex frame>. The values are those the test renders:
target 12345 counts, speed 60 rpm = 3200 Hz at 3200 counts/rev ... as listed per profile below.
"""
from pymodbus.framer.rtu_framer import ModbusRtuFramer
from pymodbus.register_write_message import (WriteMultipleRegistersRequest,
                                             WriteSingleRegisterRequest)


def u32(value):
    value &= 0xFFFFFFFF
    return [value >> 16, value & 0xFFFF]


def frame(request, slave):
    request.unit_id = slave
    request.transaction_id = 0
    return ModbusRtuFramer(None).buildPacket(request).hex(" ").upper()


def single(address, value):
    return WriteSingleRegisterRequest(address, value)


def multi(address, values):
    return WriteMultipleRegistersRequest(address, values)


CASES = [
    # generic: target 12345, speed_hz 1600, accel_hz_s 4000
    ("generic", "enable", 1, single(0x0000, 1)),
    ("generic", "move.1", 1, multi(0x0010, u32(12345) + u32(1600) + u32(4000))),
    ("generic", "move.2", 1, single(0x0000, 3)),
    ("generic", "home", 1, single(0x0000, 4)),
    ("generic", "stop", 1, single(0x0000, 5)),
    # mks_servo42d: acc 240, speed_rpm 60, target 12345
    ("mks_servo42d", "enable", 1, single(0x00F3, 1)),
    ("mks_servo42d", "move", 1, multi(0x00FE, [240, 60] + u32(12345))),
    ("mks_servo42d", "home", 1, single(0x0091, 1)),
    ("mks_servo42d", "stop", 1, single(0x00F7, 1)),
    # leadshine_pr: target 12345, speed_rpm 60, accel_ms_per_krpm 1000
    ("leadshine_pr", "enable", 1, single(0x000F, 1)),
    ("leadshine_pr", "move", 1, multi(0x6200, [1] + u32(12345) + [60, 1000, 1000, 0, 0x10])),
    ("leadshine_pr", "home", 1, single(0x6002, 0x20)),
    ("leadshine_pr", "stop", 1, single(0x6002, 0x40)),
    # oriental_az: target 12345, speed_hz 1000, accel_hz_s 3000, current 1000
    ("oriental_az", "enable", 1, multi(0x007C, u32(0))),
    ("oriental_az", "move", 1,
     multi(0x0058, u32(0) + u32(1) + u32(12345) + u32(1000) + u32(3000) + u32(3000) + u32(1000)
           + u32(1))),
    ("oriental_az", "home", 1, multi(0x0078, u32(0x10))),
    ("oriental_az", "stop", 1, multi(0x0078, u32(0x20))),
]

for profile, command, slave, request in CASES:
    print(profile, command, slave, frame(request, slave))
