#!/usr/bin/python3
"""An independent Modbus peer for revolve's tests: a drive that implements the "generic"
profile (turntable/modbus/profiles/generic.toml), written on Debian's python3-pymodbus 3.0, so
the protocol stack (framing, CRC, TCP/RTU handling) is not revolve's own.

  /usr/bin/python3 generic_drive_peer.py --tcp 127.0.0.1:0 --port-file PORT_FILE
  /usr/bin/python3 generic_drive_peer.py --rtu /path/to/pty [--baud 19200]

Register map (generic profile):
  holding 0x0000 command: 1 enable, 2 disable, 3 move, 4 home, 5 stop, 6 reset alarm
  holding 0x0010 target i32, 0x0012 speed u32 (counts/s), 0x0014 acceleration u32 (counts/s^2)
  input 0x0000 status bits: 0 enabled, 1 moving, 2 in position, 3 alarm, 4 homed
  input 0x0001 alarm code, 0x0002 position i32 (high word first)
Motion is a trapezoid computed from the clock whenever the status is read.
"""
import argparse
import asyncio
import logging
import math
import os
import signal
import sys
import time

from pymodbus.datastore import (ModbusSequentialDataBlock, ModbusServerContext,
                                ModbusSlaveContext)
from pymodbus.framer.rtu_framer import ModbusRtuFramer
from pymodbus.framer.socket_framer import ModbusSocketFramer
from pymodbus.server.async_io import ModbusSerialServer, ModbusTcpServer


class Drive:
    """The drive's state; time comes from time.monotonic()."""

    def __init__(self, steps_per_rev):
        self.steps_per_rev = steps_per_rev
        self.enabled = False
        self.homed = False
        self.alarm = 0
        self.position = 0.0
        self.target = 0.0
        self.motion = None  # (start_time, start_pos, target, speed, accel, homing)

    def _advance(self):
        if self.motion is None:
            return
        start, origin, target, speed, accel, homing = self.motion
        distance = abs(target - origin)
        sign = 1.0 if target >= origin else -1.0
        t = time.monotonic() - start
        t_acc = speed / accel
        if distance < speed * t_acc:  # triangle
            t_acc = math.sqrt(distance / accel)
            speed = accel * t_acc
            cruise = 0.0
        else:
            cruise = (distance - speed * t_acc) / speed
        total = 2 * t_acc + cruise
        if t >= total:
            self.position = target
            self.motion = None
            if homing:
                self.homed = True
            return
        if t < t_acc:
            travel = 0.5 * accel * t * t
        elif t < t_acc + cruise:
            travel = 0.5 * accel * t_acc * t_acc + speed * (t - t_acc)
        else:
            rest = total - t
            travel = distance - 0.5 * accel * rest * rest
        self.position = origin + sign * travel

    def _start(self, target, speed, accel, homing):
        self._advance()
        speed = speed if speed > 0 else self.steps_per_rev
        accel = accel if accel > 0 else 10 * self.steps_per_rev
        self.target = target
        self.motion = (time.monotonic(), self.position, target, speed, accel, homing)

    def command(self, code, holding):
        self._advance()
        if code == 1 and not self.alarm:
            self.enabled = True
        elif code == 2:
            self.enabled = False
            self.motion = None
            self.target = self.position
        elif code == 3 and self.enabled and not self.alarm:
            target = (holding[0x10] << 16) | holding[0x11]
            if target >= 1 << 31:
                target -= 1 << 32
            speed = (holding[0x12] << 16) | holding[0x13]
            accel = (holding[0x14] << 16) | holding[0x15]
            self._start(float(target), float(speed), float(accel), False)
        elif code == 4 and self.enabled and not self.alarm:
            self.homed = False
            self._start(0.0, 0.0, 0.0, True)
        elif code == 5:
            self._advance()
            self.motion = None
            self.target = self.position
        elif code == 6:
            self.alarm = 0

    def inputs(self):
        self._advance()
        moving = self.motion is not None
        in_position = not moving and not self.alarm and abs(self.position - self.target) < 0.5
        status = ((1 if self.enabled else 0) | (2 if moving else 0) | (4 if in_position else 0)
                  | (8 if self.alarm else 0) | (16 if self.homed else 0))
        position = int(round(self.position)) & 0xFFFFFFFF
        return [status, self.alarm, position >> 16, position & 0xFFFF]


class HoldingBlock(ModbusSequentialDataBlock):
    def __init__(self, drive):
        super().__init__(0, [0] * 0x100)
        self.drive = drive

    def setValues(self, address, values):  # noqa: N802 (pymodbus API)
        super().setValues(address, values)
        if address <= 0 < address + len(values):
            self.drive.command(values[0 - address], self.values)


class InputBlock(ModbusSequentialDataBlock):
    def __init__(self, drive):
        super().__init__(0, [0] * 0x100)
        self.drive = drive

    def getValues(self, address, count=1):  # noqa: N802 (pymodbus API)
        self.values[0:4] = self.drive.inputs()
        return super().getValues(address, count)


async def main():
    parser = argparse.ArgumentParser()
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--tcp")
    group.add_argument("--rtu")
    parser.add_argument("--baud", type=int, default=19200)
    parser.add_argument("--port-file")
    parser.add_argument("--steps-per-rev", type=int, default=3200)
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)

    drive = Drive(args.steps_per_rev)
    slave = ModbusSlaveContext(hr=HoldingBlock(drive), ir=InputBlock(drive), zero_mode=True)
    context = ModbusServerContext(slaves=slave, single=True)
    loop = asyncio.get_running_loop()
    stop = loop.create_future()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, lambda: stop.done() or stop.set_result(True))

    if args.tcp:
        host, port = args.tcp.rsplit(":", 1)
        server = ModbusTcpServer(context, ModbusSocketFramer, None, (host, int(port)),
                                 allow_reuse_address=True)
        task = asyncio.create_task(server.serve_forever())
        await server.serving
        port = server.server.sockets[0].getsockname()[1]
        if args.port_file:
            with open(args.port_file + ".tmp", "w") as f:
                f.write(f"{port}\n")
            os.rename(args.port_file + ".tmp", args.port_file)
        print(f"pymodbus peer: generic drive on tcp {host}:{port}", flush=True)
        await stop
        await server.server_close()
        task.cancel()
    else:
        server = ModbusSerialServer(context, ModbusRtuFramer, port=args.rtu, baudrate=args.baud,
                                    bytesize=8, parity="N", stopbits=1, timeout=0.005)
        await server.start()
        print(f"pymodbus peer: generic drive on rtu {args.rtu} {args.baud} 8N1", flush=True)
        await stop
        await server.shutdown()


if __name__ == "__main__":
    asyncio.run(main())
    sys.exit(0)
