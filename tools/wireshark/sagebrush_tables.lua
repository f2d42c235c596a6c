-- GENERATED from the sagebrush-protocol crate's tables (crates/protocol/src/dissector.rs):
-- do not edit. Regenerate: cargo run -p sagebrush-protocol --example gen_dissector_tables
local T = {}

-- Commands by mnemonic (Tables 4, 11, 16): answer is ack, result or optional
-- (a rev 1.9 set/read command answers with a result only when it reads);
-- fixed: the row takes no arguments (its mnemonic is its wire form).
T.commands = {
    ["AW"] = { answer = "result", description = "AW: awake status (Table 4; result Table 5).", shape = "awake", fixed = true },
    ["B?"] = { answer = "result", description = "B?: maximum data rate, C0..CF (Table 4).", shape = "maxrate", fixed = true },
    ["D?"] = { answer = "result", description = "D?: identification (Table 4; result Table 6).", shape = "identity", fixed = true },
    ["E?"] = { answer = "result", description = "E?: error codes (Table 4; result Table 6A).", shape = "errors", fixed = true },
    ["I?"] = { answer = "result", description = "I?: status bits (Table 4; result Table 6B).", shape = "statusbits", fixed = true },
    ["G?"] = { answer = "result", description = "G?: rate gains (Table 4; result Table 8).", shape = "gains", fixed = true },
    ["IX"] = { answer = "result", description = "IX: initialisation (Table 4; result Table 9, which takes long).", shape = "init", fixed = true },
    ["LR"] = { answer = "result", description = "LR: relay status (Table 4; result Table 4A).", shape = "relays", fixed = true },
    ["LC"] = { answer = "ack", description = "LC: clear software limits (Table 4).", fixed = true },
    ["L?"] = { answer = "result", description = "L?: software limits (Table 4; result Table 10).", shape = "limits", fixed = true },
    ["A?"] = { answer = "result", description = "A?: both accelerations (Table 11; result Table 13, protocol-notes E7).", shape = "accels", fixed = true },
    ["HA"] = { answer = "ack", description = "HA: halt, stores the position, motors off (Table 11).", fixed = true },
    ["HV"] = { answer = "result", description = "HV: verify home (Table 11; result Table 14).", shape = "home", fixed = true },
    ["HO"] = { answer = "ack", description = "HO: go home (0, 0) (Table 11).", fixed = true },
    ["HS"] = { answer = "ack", description = "HS: stop, motors off (Table 11).", fixed = true },
    ["P?"] = { answer = "result", description = "P?: current position (Table 11; result Table 15).", shape = "position", fixed = true },
    ["PL"] = { answer = "ack", description = "PL: pan left (CW) until PS (Table 11).", fixed = true },
    ["PR"] = { answer = "ack", description = "PR: pan right (CCW) until PS (Table 11).", fixed = true },
    ["PS"] = { answer = "ack", description = "PS: pan stop (Table 11).", fixed = true },
    ["PT"] = { answer = "ack", description = "PT: stop motion (Table 11).", fixed = true },
    ["R?"] = { answer = "result", description = "R?: both rates (Table 11; result Table 13, protocol-notes E7).", shape = "rates", fixed = true },
    ["TD"] = { answer = "ack", description = "TD: tilt down (CW) until TS (Table 11).", fixed = true },
    ["TS"] = { answer = "ack", description = "TS: tilt stop (Table 11).", fixed = true },
    ["TU"] = { answer = "ack", description = "TU: tilt up (CCW) until TS (Table 11).", fixed = true },
    ["CN"] = { answer = "ack", description = "CN: camera and lens power on (Table 16).", fixed = true },
    ["CX"] = { answer = "ack", description = "CX: camera and lens power off (Table 16).", fixed = true },
    ["FA"] = { answer = "ack", description = "FA: auto-focus on (Table 16; not implemented by the gimbal).", fixed = true },
    ["FF"] = { answer = "ack", description = "FF: focus far until FS (Table 16).", fixed = true },
    ["FN"] = { answer = "ack", description = "FN: focus near until FS (Table 16).", fixed = true },
    ["FS"] = { answer = "ack", description = "FS: focus stop (Table 16).", fixed = true },
    ["FX"] = { answer = "ack", description = "FX: auto-focus off (Table 16; not implemented by the gimbal).", fixed = true },
    ["V?"] = { answer = "result", description = "V?: lens position (Table 16; result Table 17).", shape = "lens", fixed = true },
    ["ZI"] = { answer = "ack", description = "ZI: zoom in until ZS (Table 16).", fixed = true },
    ["ZO"] = { answer = "ack", description = "ZO: zoom out until ZS (Table 16).", fixed = true },
    ["ZS"] = { answer = "ack", description = "ZS: zoom stop (Table 16).", fixed = true },
    ["#NN"] = { answer = "ack", description = "#NN: set device address/ID (Table 4)." },
    ["Cn"] = { answer = "ack", description = "C0..CF: set communication data rate (Table 4; C8..CF reserved, protocol-notes E15)." },
    ["GRPnn"] = { answer = "ack", description = "GRPnn / GRTnn: set a rate gain (Table 4; value Table 7)." },
    ["GRTnn"] = { answer = "ack", description = "GRPnn / GRTnn: set a rate gain (Table 4; value Table 7)." },
    ["L0..L3"] = { answer = "ack", description = "L0..L3: open relay (Table 4)." },
    ["L8..LB"] = { answer = "ack", description = "L8..LB: close relay (Table 4)." },
    ["LS"] = { answer = "ack", description = "LS + 12 hex: set software limits (Table 4; values Table 10)." },
    ["AP?"] = { answer = "result", description = "AP? / AT?: one axis (Table 11, protocol-notes E7). Before APnnnn.", shape = "accel" },
    ["AT?"] = { answer = "result", description = "AP? / AT?: one axis (Table 11, protocol-notes E7). Before APnnnn.", shape = "accel" },
    ["APnnnn"] = { answer = "ack", description = "APnnnn / ATnnnn (Table 11; value Table 12)." },
    ["ATnnnn"] = { answer = "ack", description = "APnnnn / ATnnnn (Table 11; value Table 12)." },
    ["Paaaaeeee"] = { answer = "ack", description = "Paaaaeeee: go to position (Table 11; values Table 15)." },
    ["Pnn"] = { answer = "ack", description = "Pnn: go to preset (Table 11)." },
    ["P?nn"] = { answer = "result", description = "P?nn: preset position (Table 11; result Table 15).", shape = "position" },
    ["RP?"] = { answer = "result", description = "RP? / RT?: one axis (Table 11, protocol-notes E7). Before RPnnnn.", shape = "rate" },
    ["RT?"] = { answer = "result", description = "RP? / RT?: one axis (Table 11, protocol-notes E7). Before RPnnnn.", shape = "rate" },
    ["RPnnnn"] = { answer = "ack", description = "RPnnnn / RTnnnn (Table 11; value Table 12)." },
    ["RTnnnn"] = { answer = "ack", description = "RPnnnn / RTnnnn (Table 11; value Table 12)." },
    ["SPn"] = { answer = "ack", description = "SP0..SPF / ST0..STF: proportional speed (Table 11). Before Snn." },
    ["STn"] = { answer = "ack", description = "SP0..SPF / ST0..STF: proportional speed (Table 11). Before Snn." },
    ["Snn"] = { answer = "ack", description = "Snn: store current position as preset (Table 11)." },
    ["S?nn"] = { answer = "result", description = "S?nn: position stored at preset (Table 11; result Table 15).", shape = "position" },
    ["VMn"] = { answer = "ack", description = "VMn: vector motion on/off (Table 11)." },
    ["Fn"] = { answer = "ack", description = "F0..F9: focus speed (Table 16)." },
    ["Vzzzfff"] = { answer = "ack", description = "Vzzzfff: lens go-to (Table 16; values Table 17)." },
    ["Zn"] = { answer = "ack", description = "Z0..Z9: zoom speed (Table 16)." },
    ["ZA..ZF"] = { answer = "ack", description = "ZA..ZF: digital zoom (Table 16; not implemented by the gimbal)." },
    ["*xpc"] = { answer = "ack", description = "*xpc,baud,data,stop,parity (Table 16; fields Table 18)." },
    ["*xpt"] = { answer = "ack", description = "*xpt + data (Table 16)." },
    ["*xprnnn"] = { answer = "result", description = "*xprnnn: receive up to nnn bytes (Table 16; decimal, protocol-notes E14).", shape = "auxdata" },
    ["*xpn"] = { answer = "result", description = "*xpn: characters waiting (Table 16; decimal, protocol-notes E14).", shape = "auxcount" },
    ["*xpf"] = { answer = "ack", description = "*xpf: flush (Table 16)." },
    ["unknown"] = { answer = "ack", description = "A payload that fits no command: a device answers it with NIC. No row parses to it: Command::parse gives it for what no row takes." },
}

-- Rev 1.9 commands published by name only (1.2), matched as prefixes in this order.
T.extended = {
    { name = "HP", answer = "ack", description = "HP: go to the gimbal position saved by HA." },
    { name = "VP", answer = "ack", description = "VP: go to the lens position saved by HA." },
    { name = "VS", answer = "result", shape = "raw", description = "VS: camera and relay status." },
    { name = "F?", answer = "result", shape = "raw", description = "F?: current focus speed number." },
    { name = "Z?", answer = "result", shape = "raw", description = "Z?: current zoom speed number." },
    { name = "C?", answer = "result", shape = "raw", description = "C?: lens software limits or preset position values." },
    { name = "*dA", answer = "result", shape = "raw", description = "*dA: analog channel values." },
    { name = "*di", answer = "result", shape = "raw", description = "*di: digital input values." },
    { name = "*do", answer = "result", shape = "raw", description = "*do: digital output values." },
    { name = "*dl", answer = "result", shape = "raw", description = "*dl: status messages." },
    { name = "*dm", answer = "ack", description = "*dm: set loop mode." },
    { name = "*mr", answer = "ack", description = "*mr: rate commands." },
    { name = "*me", answer = "optional", shape = "raw", description = "*me: send/read position in encoder counts." },
    { name = "*mp", answer = "optional", shape = "raw", description = "*mp: send/read position in floating point." },
    { name = "*mu", answer = "optional", shape = "raw", description = "*mu: set/read user parameters." },
    { name = "*sa", answer = "optional", shape = "raw", description = "*sa: set/read inertial gain." },
    { name = "*sgr", answer = "optional", shape = "raw", description = "*sgr: set/read rate gain in floating point." },
    { name = "*sgp", answer = "optional", shape = "raw", description = "*sgp: set/read position gain in floating point." },
    { name = "*sl", answer = "optional", shape = "raw", description = "*sl: set/read rate/acceleration limits." },
}

-- Table 4 `Cn`: data rate codes, bit/s (8..F reserved).
T.data_rates = { [0] = 1200, [1] = 2400, [2] = 4800, [3] = 9600, [4] = 19200, [5] = 38400, [6] = 57600, [7] = 115200, }

-- Table 5: awake status bits, lowest first.
T.awake_bits = {
    { mask = 1, name = "azimuth (pan) not initialised" },
    { mask = 2, name = "elevation (tilt) not initialised" },
    { mask = 4, name = "motors off" },
    { mask = 8, name = "error condition" },
}

-- A delivery report's payload: its mark and length (ARCHITECTURE "Delivery contract").
T.report_mark = "!"
T.report_len = 13

-- Delivery report codes: name and meaning.
T.report_codes = {
    [0x00] = { name = "delivered", meaning = "delivered" },
    [0x01] = { name = "device_silent", meaning = "the device did not acknowledge it (silent after all retries)" },
    [0x02] = { name = "device_nak", meaning = "the device answered NAK to every transmission" },
    [0x03] = { name = "no_such_port", meaning = "no such port on the GCU" },
    [0x04] = { name = "port_closed", meaning = "the port is not open" },
    [0x05] = { name = "queue_full", meaning = "a queue on the way was full" },
    [0x06] = { name = "no_route", meaning = "no route to the destination group" },
    [0x07] = { name = "link_down", meaning = "the link toward the destination is down or did not acknowledge" },
    [0x08] = { name = "shutting_down", meaning = "the GCU is shutting down" },
    [0x09] = { name = "source_not_allowed", meaning = "the link may not speak as that source group" },
    [0x0A] = { name = "loop", meaning = "the only route leads back where the command came from" },
    [0x0B] = { name = "not_confirmed", meaning = "delivery was not confirmed in time (it may still execute)" },
    [0x0C] = { name = "expired", meaning = "it waited in a queue too long and was given up unsent" },
    [0x0D] = { name = "not_in_control", meaning = "another link of equal or higher priority controls the gimbal" },
    [0x0E] = { name = "travel_limit", meaning = "its target lies outside the gimbal's travel limits" },
    [0x0F] = { name = "keep_out", meaning = "its path may enter a keep-out zone" },
    [0x10] = { name = "position_unknown", meaning = "the gimbal's position is unknown and it has limits or zones" },
    [0x11] = { name = "superseded", meaning = "a stop for the same gimbal overtook it before it reached the bus" },
    [0x12] = { name = "ungoverned", meaning = "the gimbal has limits, zones, park or a tour, and the command moves or changes it where gcud cannot bound it (the allow list of its gimbal entry may name it)" },
    [0x13] = { name = "stops_limited", meaning = "a stop from a link below the gimbal's holder, sooner than one second after its last" },
    [0x14] = { name = "rate_unknown", meaning = "a speed change whose rate gcud does not know, while the gimbal slews toward a limit or zone" },
    [0x15] = { name = "preset_unknown", meaning = "the gimbal did not say where the preset lies, and it has limits or zones" },
    [0x16] = { name = "not_permitted", meaning = "the link's priority does not permit it (tours, reading a gimbal's rules)" },
}

-- Capture record kinds (header byte 1, docs/capture.md).
T.record_kinds = {
    [1] = { name = "frame", meaning = "a frame whose checksum holds" },
    [2] = { name = "ack", meaning = "an ACK byte" },
    [3] = { name = "nak", meaning = "a NAK byte" },
    [4] = { name = "nic", meaning = "a NIC byte (?)" },
    [5] = { name = "noise", meaning = "bytes between frames that are part of nothing" },
    [6] = { name = "bad_checksum", meaning = "a frame-sized candidate whose checksum failed: the bytes its length byte claims" },
}

-- Capture record directions (header byte 2), seen from the capturing program.
T.directions = {
    [1] = { name = "inbound", meaning = "read by the capturing program" },
    [2] = { name = "outbound", meaning = "written by the capturing program" },
}

-- Capture record roles (header byte 3): which way commands flow on the line.
T.roles = {
    [0] = { name = "unknown", meaning = "not known to the capturing program" },
    [1] = { name = "master", meaning = "the capturing program sends the commands: a gcud device port or downstream link, gimbalctl" },
    [2] = { name = "responder", meaning = "the capturing program receives the commands: a gcud client or upstream link, gimbalsim" },
}

-- Bytes of the capture record header before the raw bytes (docs/capture.md).
T.record_header_len = 8

return T
