-- Wireshark dissector for Sagebrush gimbal protocol rev 1.9 captures
-- written by sagebrush_host::capture (gcud [capture], see docs/capture.md).
--
-- Link type LINKTYPE_USER0 (147). Each record: an 8-byte header
--   version (1), kind (frame, ACK, NAK, NIC, noise, bad checksum),
--   direction (inbound, outbound, seen from the capturing program),
--   role (unknown; master: the capturer sends the commands; responder: it
--   receives them), whose codes are T.record_kinds, T.directions, T.roles,
--   interface number (u32 big endian, the capturing program's own)
-- then the raw bytes of the frame, byte or noise.
--
-- Install: copy it and sagebrush_tables.lua (generated from the Rust tables;
-- it must sit next to this file) to ~/.local/lib/wireshark/plugins/ (or run
--   tshark -X lua_script:tools/wireshark/sagebrush.lua -r FILE).
-- Pairing rules (results, ACK/NAK/NIC, reports, retransmissions, time-outs):
-- docs/capture.md, "Pairing".

local p = Proto("sagebrush", "Sagebrush gimbal protocol rev 1.9")

-- The protocol's tables, generated from the Rust crate (sagebrush_tables.lua
-- next to this file; crates/protocol/src/dissector.rs writes it).
local T = dofile((debug.getinfo(1, "S").source:match("^@(.*[/\\])") or "") .. "sagebrush_tables.lua")

-- The record header's codes by name (K.frame, D.inbound, R.master, ...) and
-- their labels, from the generated tables (crates/protocol/src/capture_record.rs).
local function codes(table)
    local by_name, labels = {}, {}
    for code, r in pairs(table) do
        by_name[r.name] = code
        labels[code] = r.name:gsub("_", " ") .. ": " .. r.meaning
    end
    return by_name, labels
end
local K, kinds = codes(T.record_kinds)
local D, directions = codes(T.directions)
local R, roles = codes(T.roles)

local f = {
    version = ProtoField.uint8("sagebrush.version", "Record version"),
    kind = ProtoField.uint8("sagebrush.kind", "Record kind", base.DEC, kinds),
    direction = ProtoField.uint8("sagebrush.direction", "Direction", base.DEC, directions),
    role = ProtoField.uint8("sagebrush.role", "Line role", base.DEC, roles),
    iface = ProtoField.uint32("sagebrush.interface", "Interface number (capturing program's)"),
    start = ProtoField.uint8("sagebrush.start", "Start character", base.HEX),
    dest_group = ProtoField.uint8("sagebrush.dest.group", "Destination group", base.DEC),
    dest_port = ProtoField.uint8("sagebrush.dest.port", "Destination port", base.DEC),
    dest_device = ProtoField.uint8("sagebrush.dest.device", "Destination device", base.DEC),
    source = ProtoField.uint8("sagebrush.source", "Source group", base.DEC),
    address = ProtoField.string("sagebrush.address", "Destination (group.port.device)"),
    length = ProtoField.uint8("sagebrush.length", "Length byte", base.DEC),
    payload_len = ProtoField.uint16("sagebrush.payload_len", "Payload length", base.DEC),
    payload = ProtoField.string("sagebrush.payload", "Payload"),
    checksum = ProtoField.uint8("sagebrush.checksum", "Checksum", base.HEX),
    checksum_expected = ProtoField.uint8("sagebrush.checksum.expected", "Checksum computed", base.HEX),
    checksum_bad = ProtoField.bool("sagebrush.checksum.bad", "Checksum bad"),
    type = ProtoField.string("sagebrush.type", "Frame type"),
    cmd = ProtoField.string("sagebrush.cmd", "Command"),
    cmd_desc = ProtoField.string("sagebrush.cmd.description", "Command description"),
    pan_deg = ProtoField.double("sagebrush.pan_deg", "Pan position (deg)"),
    tilt_deg = ProtoField.double("sagebrush.tilt_deg", "Tilt position (deg)"),
    pan_rate = ProtoField.double("sagebrush.pan_rate", "Pan rate (deg/s)"),
    tilt_rate = ProtoField.double("sagebrush.tilt_rate", "Tilt rate (deg/s)"),
    rate = ProtoField.double("sagebrush.rate", "Rate (deg/s)"),
    pan_accel = ProtoField.double("sagebrush.pan_accel", "Pan acceleration (deg/s^2)"),
    tilt_accel = ProtoField.double("sagebrush.tilt_accel", "Tilt acceleration (deg/s^2)"),
    accel = ProtoField.double("sagebrush.accel", "Acceleration (deg/s^2)"),
    axis = ProtoField.string("sagebrush.axis", "Axis"),
    speed = ProtoField.uint8("sagebrush.speed", "Proportional speed (0 slow .. 15 max)"),
    preset = ProtoField.uint8("sagebrush.preset", "Preset", base.HEX),
    gain = ProtoField.double("sagebrush.gain", "Rate gain"),
    pan_gain = ProtoField.double("sagebrush.pan_gain", "Pan rate gain"),
    tilt_gain = ProtoField.double("sagebrush.tilt_gain", "Tilt rate gain"),
    data_rate = ProtoField.uint32("sagebrush.data_rate", "Data rate (bit/s)"),
    device_id = ProtoField.uint8("sagebrush.device_id", "Device ID", base.HEX),
    status = ProtoField.uint8("sagebrush.status", "Awake status bits", base.HEX),
    zoom = ProtoField.uint16("sagebrush.zoom", "Zoom position (12 bit)"),
    focus = ProtoField.uint16("sagebrush.focus", "Focus position (12 bit)"),
    id_revision = ProtoField.string("sagebrush.id.revision", "Protocol revision"),
    id_name = ProtoField.string("sagebrush.id.name", "Device name"),
    id_serial = ProtoField.string("sagebrush.id.serial", "Serial number"),
    swapped = ProtoField.bool("sagebrush.table3_swap", "Table 3 header swap holds"),
    response_to = ProtoField.framenum("sagebrush.response_to", "Result of command in frame", base.NONE, frametype.RESPONSE),
    response_in = ProtoField.framenum("sagebrush.response_in", "Result in frame", base.NONE, frametype.REQUEST),
    ack_of = ProtoField.framenum("sagebrush.ack_of", "Answers command in frame", base.NONE, frametype.ACK),
    ack_in = ProtoField.framenum("sagebrush.ack_in", "Acknowledged in frame", base.NONE, frametype.REQUEST),
    retransmission_of = ProtoField.framenum("sagebrush.retransmission_of", "Retransmission of frame"),
    report_code = ProtoField.uint8("sagebrush.report.code", "Delivery report code", base.HEX),
    report_reason = ProtoField.string("sagebrush.report.reason", "Delivery outcome"),
    report_address = ProtoField.string("sagebrush.report.address", "Reported command address"),
    report_checksum = ProtoField.uint8("sagebrush.report.checksum", "Reported command checksum", base.HEX),
    report_group = ProtoField.uint8("sagebrush.report.group", "Reporting failure group"),
    report_of = ProtoField.framenum("sagebrush.report_of", "Report on command in frame", base.NONE, frametype.RESPONSE),
    noise = ProtoField.bytes("sagebrush.noise", "Noise bytes"),
    pan_bits = ProtoField.uint16("sagebrush.pan_bits", "Pan (azimuth) bits", base.HEX),
    tilt_bits = ProtoField.uint16("sagebrush.tilt_bits", "Tilt (elevation) bits", base.HEX),
    limit = ProtoField.uint16("sagebrush.limit", "Software limit (raw 12 bit)"),
    relays = ProtoField.uint8("sagebrush.relays", "Relays on (bit n = relay n)", base.HEX),
    home = ProtoField.string("sagebrush.home", "Verify home (limit, centre, count correct; bit 0 pan, bit 1 tilt)"),
}
local field_list = {}
for _, v in pairs(f) do field_list[#field_list + 1] = v end
p.fields = field_list

-- Expert infos: key = { text, group, severity }.
local e, expert_list = {}, {}
for key, d in pairs({
    bad_checksum = { "Bad checksum", "CHECKSUM", "ERROR" },
    nak = { "NAK: the command arrived damaged", "RESPONSE_CODE", "WARN" },
    nic = { "NIC: command not implemented by the device", "RESPONSE_CODE", "WARN" },
    retransmission = { "Retransmission", "SEQUENCE", "NOTE" },
    timeout = { "Time-out", "SEQUENCE", "WARN" },
    noise = { "Noise bytes between frames", "MALFORMED", "NOTE" },
    swap = { "Result header does not follow Table 3", "PROTOCOL", "WARN" },
    unpaired = { "No command awaits this", "SEQUENCE", "NOTE" },
    undelivered = { "Command not delivered", "RESPONSE_CODE", "WARN" },
}) do
    e[key] = ProtoExpert.new("sagebrush.expert." .. key, d[1], expert.group[d[2]], expert.severity[d[3]])
    expert_list[#expert_list + 1] = e[key]
end
p.experts = expert_list


-- Table 2 meanings.
local function group_name(v)
    if v == 0 then return "MCU" elseif v == 255 then return "broadcast: every GCU" end
    return "GCU " .. v
end
local function port_name(v)
    if v == 0 then return "GCU/MCU link (the control unit itself)" elseif v == 255 then return "broadcast: every port" end
    return "port " .. v
end
local function device_name(v)
    if v == 0 then return "the MCU/GCU itself" elseif v == 255 then return "broadcast: every device on the port" end
    return "device " .. v
end

local function hexval(s)
    if s == nil or s == "" or not s:match("^[0-9A-Fa-f]+$") then return nil end
    return tonumber(s, 16)
end
local function signed16(v) if v >= 32768 then return v - 65536 end return v end

local rates = T.data_rates

local report_codes = {}
for code, r in pairs(T.report_codes) do report_codes[code] = r.name:gsub("_", " ") end

-- Commands (Tables 4, 11, 16, the rev 1.9 list), told apart by first
-- character and length as in crates/protocol/src/command.rs. Mnemonics,
-- descriptions, answers and result shapes come from the generated tables.
-- Returns mnemonic, description, result shape (nil: ACK only), whether the
-- result is optional (a rev 1.9 set/read command answers only when it
-- reads), and a list of {field, value, offset, length} decoded arguments.
local function parse_command(s)
    local n = #s
    local a = {}
    local function arg(field, value, offset, len) a[#a + 1] = { field, value, offset, len } end
    local function row(m, extra)
        local r = T.commands[m] or T.commands["unknown"]
        return m, r.description .. (extra or ""), r.shape, r.answer == "optional", a
    end
    -- GCU commands on port 0 (ARCHITECTURE "Governance", the protocol
    -- crate's module gcu): ~R has no result, ~C, ~T and ~B one (shown raw).
    if s:sub(1, 1) == "~" then
        local gcu = {
            R = "~R PPDD: release control of gimbal PP.DD (GCU command)",
            C = "~C PPDD: who controls gimbal PP.DD (GCU command)",
            T = "~T+name, ~T-name, ~T?: start, stop or list tours (GCU command)",
            B = "~B PPDD: travel limits and keep-out zones of gimbal PP.DD (GCU command)",
        }
        local k = s:sub(2, 2)
        return "~" .. k, gcu[k] or "unknown GCU command", (k == "C" or k == "T" or k == "B") and "raw" or nil, false, a
    end
    for _, ext in ipairs(T.extended) do
        if s:sub(1, #ext.name) == ext.name then
            return ext.name, ext.description .. " (raw arguments)", ext.shape, ext.answer == "optional", a
        end
    end
    if T.commands[s] and T.commands[s].fixed then return row(s) end
    local c = s:sub(1, 1)
    local axis_of = { P = "pan", T = "tilt" }
    local ax = s:sub(2, 2)
    -- Per-axis queries and settings (Table 11; values Table 12, hundredths):
    -- the letter, the axis, then ? or four hex digits.
    local per_axis_value = { A = f.accel, R = f.rate }
    if per_axis_value[c] and axis_of[ax] and n == 3 and s:sub(3, 3) == "?" then
        arg(f.axis, axis_of[ax], 1, 1)
        return row(c .. ax .. "?")
    elseif per_axis_value[c] and axis_of[ax] and n == 6 and hexval(s:sub(3, 6)) then
        arg(f.axis, axis_of[ax], 1, 1)
        arg(per_axis_value[c], hexval(s:sub(3, 6)) / 100, 2, 4)
        return row(c .. ax .. "nnnn")
    elseif c == "#" and n == 3 and hexval(s:sub(2, 3)) then
        arg(f.device_id, hexval(s:sub(2, 3)), 1, 2)
        return row("#NN")
    elseif c == "C" and n == 2 and hexval(ax) then
        local bps = T.data_rates[hexval(ax)]
        if bps then arg(f.data_rate, bps, 1, 1) end
        return row("Cn", bps and "" or " [reserved code]")
    elseif c == "F" and n == 2 and ax:match("%d") then
        arg(f.speed, tonumber(ax), 1, 1)
        return row("Fn")
    elseif s:sub(1, 2) == "GR" and n == 5 and axis_of[s:sub(3, 3)] and hexval(s:sub(4, 5)) then
        arg(f.axis, axis_of[s:sub(3, 3)], 2, 1)
        arg(f.gain, hexval(s:sub(4, 5)) / 10, 3, 2)
        return row("GR" .. s:sub(3, 3) .. "nn")
    elseif c == "L" and n == 2 and ax:match("[0-3]") then
        return row("L0..L3", " [relay " .. ax .. "]")
    elseif c == "L" and n == 2 and ax:match("[89ABab]") then
        return row("L8..LB", " [relay " .. (hexval(ax) - 8) .. "]")
    elseif s:sub(1, 2) == "LS" and n == 14 then
        return row("LS")
    elseif c == "P" and n == 3 and hexval(s:sub(2, 3)) then
        arg(f.preset, hexval(s:sub(2, 3)), 1, 2)
        return row("Pnn")
    elseif s:sub(1, 2) == "P?" and n == 4 and hexval(s:sub(3, 4)) then
        arg(f.preset, hexval(s:sub(3, 4)), 2, 2)
        return row("P?nn")
    elseif c == "P" and n == 9 and hexval(s:sub(2, 9)) then
        arg(f.pan_deg, signed16(hexval(s:sub(2, 5))) / 100, 1, 4)
        arg(f.tilt_deg, signed16(hexval(s:sub(6, 9))) / 100, 5, 4)
        return row("Paaaaeeee")
    elseif s:sub(1, 2) == "S?" and n == 4 and hexval(s:sub(3, 4)) then
        arg(f.preset, hexval(s:sub(3, 4)), 2, 2)
        return row("S?nn")
    elseif c == "S" and n == 3 and axis_of[ax] and hexval(s:sub(3, 3)) then
        arg(f.axis, axis_of[ax], 1, 1)
        arg(f.speed, hexval(s:sub(3, 3)), 2, 1)
        return row("S" .. ax .. "n")
    elseif c == "S" and n == 3 and hexval(s:sub(2, 3)) then
        arg(f.preset, hexval(s:sub(2, 3)), 1, 2)
        return row("Snn")
    elseif s:sub(1, 2) == "VM" and n == 3 and s:sub(3, 3):match("[01]") then
        return row("VMn", s:sub(3, 3) == "1" and " [on]" or " [off]")
    elseif c == "V" and n == 7 and hexval(s:sub(2, 7)) then
        arg(f.zoom, hexval(s:sub(2, 4)), 1, 3)
        arg(f.focus, hexval(s:sub(5, 7)), 4, 3)
        return row("Vzzzfff")
    elseif c == "Z" and n == 2 and ax:match("%d") then
        arg(f.speed, tonumber(ax), 1, 1)
        return row("Zn")
    elseif c == "Z" and n == 2 and ax:match("[A-Fa-f]") then
        return row("ZA..ZF")
    elseif s:sub(1, 2) == "*x" and n >= 4 then
        local ops = { c = "*xpc", t = "*xpt", r = "*xprnnn", n = "*xpn", f = "*xpf" }
        local m = ops[s:sub(4, 4)]
        if m then return row(m, " [port " .. s:sub(3, 3) .. "]") end
    end
    return row("unknown")
end

-- Decodes a result payload for the command's shape (crates/protocol/src/reply.rs).
local function decode_result(shape, cmd_payload, s, tree, range)
    local skip = 0
    if shape ~= "raw" and cmd_payload and #s > #cmd_payload and s:sub(1, #cmd_payload) == cmd_payload then
        skip = #cmd_payload -- an echo of the command (protocol-notes E6)
    end
    local body = s:sub(skip + 1)
    local function at(off, len) return range(skip + off, len) end
    if shape == "position" then
        local o = 0
        if #body == 9 and body:sub(1, 1) == "P" then o = 1 end
        local pan, tilt = hexval(body:sub(o + 1, o + 4)), hexval(body:sub(o + 5, o + 8))
        if pan and tilt and #body == o + 8 then
            tree:add(f.pan_deg, at(o, 4), signed16(pan) / 100)
            tree:add(f.tilt_deg, at(o + 4, 4), signed16(tilt) / 100)
            return string.format("pan %.2f deg, tilt %.2f deg", signed16(pan) / 100, signed16(tilt) / 100)
        end
    elseif shape == "rates" or shape == "accels" then
        local pan, tilt = hexval(body:sub(1, 4)), hexval(body:sub(5, 8))
        if pan and tilt and #body == 8 then
            local fp, ft, unit = f.pan_rate, f.tilt_rate, "deg/s"
            if shape == "accels" then fp, ft, unit = f.pan_accel, f.tilt_accel, "deg/s^2" end
            tree:add(fp, at(0, 4), pan / 100)
            tree:add(ft, at(4, 4), tilt / 100)
            return string.format("pan %.2f %s, tilt %.2f %s", pan / 100, unit, tilt / 100, unit)
        end
    elseif shape == "rate" or shape == "accel" then
        local v = hexval(body)
        if v and #body == 4 then
            tree:add(shape == "rate" and f.rate or f.accel, at(0, 4), v / 100)
            return string.format("%.2f %s", v / 100, shape == "rate" and "deg/s" or "deg/s^2")
        end
    elseif shape == "gains" then
        local pan, tilt = hexval(body:sub(1, 2)), hexval(body:sub(3, 4))
        if pan and tilt then
            tree:add(f.pan_gain, at(0, 2), pan / 10)
            tree:add(f.tilt_gain, at(2, 2), tilt / 10)
            return string.format("pan gain %.1f, tilt gain %.1f", pan / 10, tilt / 10)
        end
    elseif shape == "awake" then
        local v = hexval(body) or (#body == 1 and body:byte(1) <= 15 and body:byte(1)) or nil
        if v and #body == 1 then
            tree:add(f.status, at(0, 1), v)
            if v == 0 then return "hardware functioning properly" end
            local bits = {}
            for _, b in ipairs(T.awake_bits) do
                if math.floor(v / b.mask) % 2 == 1 then bits[#bits + 1] = b.name end
            end
            return table.concat(bits, ", ")
        end
    elseif shape == "maxrate" then
        local code = hexval(body:gsub("^C", ""))
        if code then
            if rates[code] then tree:add(f.data_rate, at(0, #body), rates[code]) end
            return "maximum data rate " .. (rates[code] or "reserved") .. " bit/s"
        end
    elseif shape == "identity" then
        if #body >= 4 and hexval(body:sub(1, 2)) then
            tree:add(f.device_id, at(0, 2), hexval(body:sub(1, 2)))
            tree:add(f.id_revision, at(2, 2), body:sub(3, 4))
            local name = body:sub(5, 24):gsub("[ %z]+$", "")
            local serial = body:sub(25, 44):gsub("[ %z]+$", "")
            if #body > 4 then tree:add(f.id_name, at(4, math.min(20, #body - 4)), name) end
            if #body > 24 then tree:add(f.id_serial, at(24, math.min(20, #body - 24)), serial) end
            return string.format("ID %s rev %s %q %q", body:sub(1, 2), body:sub(3, 4), name, serial)
        end
    elseif shape == "errors" or shape == "statusbits" then
        -- Table 6A: 2 + 2 hex; Table 6B: 4 + 4 (2 + 2 accepted, protocol-notes E3).
        local w = (#body == 8) and 4 or 2
        local pan, tilt = hexval(body:sub(1, w)), hexval(body:sub(w + 1, 2 * w))
        if pan and tilt and #body == 2 * w then
            tree:add(f.pan_bits, at(0, w), pan)
            tree:add(f.tilt_bits, at(w, w), tilt)
            return string.format("pan 0x%X, tilt 0x%X", pan, tilt)
        end
    elseif shape == "limits" then
        local o = (#body == 13 and body:sub(1, 1) == "L") and 1 or 0
        local names = { "pan CCW (+)", "pan CW (-)", "tilt CCW (+)", "tilt CW (-)" }
        local parts = {}
        for i = 0, 3 do
            local v = hexval(body:sub(o + 3 * i + 1, o + 3 * i + 3))
            if not v then return nil end
            tree:add(f.limit, at(o + 3 * i, 3), v):prepend_text(names[i + 1] .. " ")
            parts[#parts + 1] = names[i + 1] .. " " .. v
        end
        return table.concat(parts, ", ")
    elseif shape == "relays" then
        local v = hexval(body:gsub("^L", ""))
        if v then
            tree:add(f.relays, at(0, #body), v)
            return string.format("relays 0x%X", v)
        end
    elseif shape == "home" then
        if #body == 3 then
            tree:add(f.home, at(0, 3), body)
            return "limit " .. body:sub(1, 1) .. ", centre " .. body:sub(2, 2) .. ", count correct " .. body:sub(3, 3)
        end
    elseif shape == "auxcount" then
        local v = tonumber(body)
        if v then return v .. " character(s) waiting" end
    elseif shape == "lens" then
        local o = (#body == 7 and body:sub(1, 1) == "V") and 1 or 0
        local z, fo = hexval(body:sub(o + 1, o + 3)), hexval(body:sub(o + 4, o + 6))
        if z and fo then
            tree:add(f.zoom, at(o, 3), z)
            tree:add(f.focus, at(o + 3, 3), fo)
            return string.format("zoom %d, focus %d", z, fo)
        end
    end
    return nil
end

-- Pairing state, built on the first pass; per-frame results kept for later passes.
local ifaces, notes = {}, {}

function p.init()
    ifaces, notes = {}, {}
end

local function iface_state(id)
    local st = ifaces[id]
    if not st then
        st = { cmds = {}, last = nil }
        ifaces[id] = st
    end
    return st
end

-- Remembers at most this many commands per interface.
local WINDOW = 64

local function first_pass(pinfo, id, kind, dir, role, info)
    local st = iface_state(id)
    local n = { }
    local now = pinfo.abs_ts
    local cmd_dir = (role == R.master) and D.outbound or D.inbound -- the direction commands travel in
    if kind == K.bad_checksum and dir ~= cmd_dir then
        st.last_reply = { num = pinfo.number }
    elseif kind == K.bad_checksum then
        -- A damaged command: the NAK that follows answers it.
        local c = { num = pinfo.number, bytes = "", time = now, group = -1, port = -1, device = -1, damaged = true }
        st.cmds[#st.cmds + 1] = c
        if #st.cmds > WINDOW then table.remove(st.cmds, 1) end
    elseif kind == K.frame and info.is_command then
        local last = st.last
        if last and last.bytes == info.bytes and not last.ack then
            n.retransmission_of = last.num
            n.timeout = string.format("no ACK/NAK to frame %d within %.0f ms: retransmitted", last.num, (now - last.time) * 1000)
        elseif role == R.master and last and last.shape and not last.optional and not last.result and last.ack then
            n.timeout = string.format("frame %d (%s) got no result before this command", last.num, last.mnemonic)
        end
        if role == R.master and not n.retransmission_of then
            -- Stop and wait: a new command means the master gave up the unacknowledged ones.
            for _, old in ipairs(st.cmds) do
                if not old.ack and not old.done then
                    old.done = true
                    n.timeout = string.format("frame %d got no ACK (given up after %d retransmission(s))",
                        old.num, old.retransmissions or 0)
                end
            end
        end
        if not n.retransmission_of then
            -- A set/read command to this device that got no result before
            -- a new command to it was a set: it awaits none any longer.
            for _, old in ipairs(st.cmds) do
                if old.optional and not old.result and old.port == info.port and old.device == info.device then
                    old.shape = nil
                end
            end
        end
        local c = { num = pinfo.number, bytes = info.bytes, time = now, group = info.group, port = info.port,
                    device = info.device, source = info.source, mnemonic = info.mnemonic, shape = info.shape,
                    optional = info.optional,
                    payload = info.payload, checksum = info.checksum }
        if n.retransmission_of then
            c = last
            c.retransmissions = (c.retransmissions or 0) + 1
        else
            st.cmds[#st.cmds + 1] = c
            if #st.cmds > WINDOW then table.remove(st.cmds, 1) end
        end
        st.last = c
    elseif kind == K.frame and info.is_report then
        for i = #st.cmds, 1, -1 do
            local c = st.cmds[i]
            if string.format("%02X%02X%02X", c.group, c.port, c.device) == info.report_address
                and c.checksum == info.report_checksum then
                n.report_of = c.num
                c.report = pinfo.number
                c.done = true
                break
            end
        end
        st.last_reply = { num = pinfo.number }
    elseif kind == K.frame then
        -- A result: the oldest command expecting one from that port and device,
        -- with the Table 3 swap first, then by port and device alone.
        local found, swapped
        for pass = 1, 2 do
            for _, c in ipairs(st.cmds) do
                if c.shape and not c.result and (c.port == info.port or c.port == 255)
                    and (c.device == info.device or c.device == 255) then
                    local swap = info.group == c.source and info.source == c.group
                    if pass == 2 or swap then
                        found, swapped = c, swap
                        break
                    end
                end
            end
            if found then break end
        end
        st.last_reply = { num = pinfo.number }
        if found then
            found.result = pinfo.number
            n.response_to = found.num
            n.swapped = swapped
            n.cmd_payload = found.payload
            n.shape = found.shape
            n.cmd_mnemonic = found.mnemonic
        end
    elseif (kind == K.ack or kind == K.nak) and dir == cmd_dir and role ~= R.unknown then
        -- The command side acknowledges a result, report or damaged frame sent to it.
        local r = st.last_reply
        if r and not r.ack then
            n.ack_of = r.num
            r.ack = pinfo.number
        end
    elseif kind == K.ack or kind == K.nak then
        for _, c in ipairs(st.cmds) do
            if not c.ack and not c.naked and not c.done then
                n.ack_of = c.num
                if kind == K.ack then c.ack = pinfo.number else c.naked = c.damaged end
                break
            end
        end
    elseif kind == K.nic then
        for i = #st.cmds, 1, -1 do
            if st.cmds[i].ack then
                n.ack_of = st.cmds[i].num
                st.cmds[i].shape = nil -- a NIC ends the wait for a result
                break
            end
        end
    end
    notes[pinfo.number] = n
    return n
end

local function checksum(buf, from, to)
    local s = 0
    for i = from, to do s = (s + buf(i, 1):uint()) % 256 end
    return s
end

function p.dissector(buf, pinfo, tree)
    local header = T.record_header_len
    if buf:len() < header then return 0 end
    pinfo.cols.protocol = "Sagebrush"
    local version, kind, dir, role = buf(0, 1):uint(), buf(1, 1):uint(), buf(2, 1):uint(), buf(3, 1):uint()
    local t = tree:add(p, buf(), "Sagebrush gimbal protocol, " .. (T.record_kinds[kind] and T.record_kinds[kind].name:gsub("_", " ") or "record kind " .. kind))
    local h = t:add(p, buf(0, header), "Capture record header")
    h:add(f.version, buf(0, 1))
    h:add(f.kind, buf(1, 1))
    h:add(f.direction, buf(2, 1))
    h:add(f.role, buf(3, 1))
    h:add(f.iface, buf(4, 4))
    -- Pairing state is per interface: by the record's own interface number,
    -- which (unlike frame.interface_id) is there on a first pass without a tree.
    local id = buf(4, 4):uint()
    if buf:len() == header then return buf:len() end
    local data = buf(header):tvb()
    local arrow = dir == D.inbound and "<- " or "-> "
    local info = {}
    local summary
    local cmd_dir = (role == R.master) and D.outbound or D.inbound

    if kind == K.noise then
        t:add(f.noise, data())
        t:add_proto_expert_info(e.noise, data:len() .. " noise byte(s)")
        pinfo.cols.info = arrow .. "noise, " .. data:len() .. " byte(s)"
        return buf:len()
    elseif kind == K.ack or kind == K.nak or kind == K.nic then
        local n = pinfo.visited and notes[pinfo.number] or first_pass(pinfo, id, kind, dir, role, info)
        n = n or {}
        summary = ({ [K.ack] = "ACK", [K.nak] = "NAK", [K.nic] = "NIC (?)" })[kind]
        if n.ack_of then t:add(f.ack_of, n.ack_of) end
        if kind == K.nak then t:add_proto_expert_info(e.nak) end
        if kind == K.nic then t:add_proto_expert_info(e.nic) end
        if not n.ack_of then t:add_proto_expert_info(e.unpaired) end
        pinfo.cols.info = arrow .. summary .. (n.ack_of and (" to frame " .. n.ack_of) or "")
        return buf:len()
    end

    -- A frame or a bad-checksum candidate.
    if data:len() < 7 then
        pinfo.cols.info = arrow .. "short frame"
        return buf:len()
    end
    local g, po, d, src = data(1, 1):uint(), data(2, 1):uint(), data(3, 1):uint(), data(4, 1):uint()
    local lenb = data(5, 1):uint()
    local plen = (lenb == 0) and 256 or lenb
    local plen_here = math.min(plen, data:len() - 7)
    t:add(f.start, data(0, 1))
    t:add(f.dest_group, data(1, 1)):append_text(" (" .. group_name(g) .. ")")
    t:add(f.dest_port, data(2, 1)):append_text(" (" .. port_name(po) .. ")")
    t:add(f.dest_device, data(3, 1)):append_text(" (" .. device_name(d) .. ")")
    t:add(f.source, data(4, 1)):append_text(" (" .. group_name(src) .. ")")
    t:add(f.address, data(1, 3), string.format("%d.%d.%d", g, po, d))
    t:add(f.length, data(5, 1)):append_text(lenb == 0 and " (0 means 256)" or "")
    t:add(f.payload_len, data(5, 1), plen)
    local payload = data(6, plen_here):string()
    local ck_range = data(6 + plen_here, 1)
    local ck = ck_range:uint()
    local expected = checksum(data, 1, 5 + plen_here)
    local ck_item = t:add(f.checksum, ck_range)
    t:add(f.checksum_expected, ck_range, expected)
    t:add(f.checksum_bad, ck_range, ck ~= expected)
    if ck ~= expected then
        ck_item:append_text(string.format(" [incorrect, should be 0x%02X]", expected))
        ck_item:add_proto_expert_info(e.bad_checksum, string.format("Bad checksum 0x%02X, computed 0x%02X", ck, expected))
    else
        ck_item:append_text(" [correct]")
    end
    t:add(f.payload, data(6, plen_here))
    local addr = string.format("%d.%d.%d from %d", g, po, d, src)
    if kind == K.bad_checksum then
        if not pinfo.visited then first_pass(pinfo, id, kind, dir, role, info) end
        pinfo.cols.info = arrow .. "BAD CHECKSUM " .. addr .. " " .. payload
        return buf:len()
    end

    info.bytes = data():string()
    info.group, info.port, info.device, info.source, info.payload, info.checksum = g, po, d, src, payload, ck
    info.is_report = (dir ~= cmd_dir or role == R.unknown) and po == 0 and d == 0 and #payload == T.report_len and payload:sub(1, 1) == T.report_mark
    info.is_command = not info.is_report and (role == R.unknown or dir == cmd_dir)
    if info.is_report then
        info.report_address = payload:sub(4, 9)
        info.report_checksum = hexval(payload:sub(10, 11))
    end
    local mnemonic, desc, shape, optional, args
    if info.is_command then
        mnemonic, desc, shape, optional, args = parse_command(payload)
        info.mnemonic, info.shape, info.optional = mnemonic, shape, optional
    end
    local n = pinfo.visited and notes[pinfo.number] or first_pass(pinfo, id, kind, dir, role, info)
    n = n or {}

    if info.is_command then
        t:add(f.type, "command")
        t:add(f.cmd, data(6, plen_here), mnemonic)
        t:add(f.cmd_desc, data(6, plen_here), desc)
        for _, a in ipairs(args) do
            t:add(a[1], data(6 + a[3], a[4]), a[2])
        end
        if n.retransmission_of then
            t:add(f.retransmission_of, n.retransmission_of)
            t:add_proto_expert_info(e.retransmission)
        end
        if n.timeout then t:add_proto_expert_info(e.timeout, n.timeout) end
        local c = nil
        for _, st in pairs(ifaces) do
            for _, x in ipairs(st.cmds) do if x.num == pinfo.number then c = x end end
        end
        if c and c.result then t:add(f.response_in, c.result) end
        if c and c.ack then t:add(f.ack_in, c.ack) end
        pinfo.cols.info = arrow .. "command " .. addr .. ": " .. mnemonic .. " " .. payload
    elseif info.is_report then
        t:add(f.type, "delivery report")
        local code = hexval(payload:sub(2, 3)) or 255
        t:add(f.report_code, data(7, 2), code)
        t:add(f.report_reason, data(7, 2), report_codes[code] or "unknown")
        t:add(f.report_address, data(9, 6), payload:sub(4, 9))
        t:add(f.report_checksum, data(15, 2), hexval(payload:sub(10, 11)) or 0)
        t:add(f.report_group, data(17, 2), hexval(payload:sub(12, 13)) or 0)
        if n.report_of then t:add(f.report_of, n.report_of) end
        if code ~= 0 then t:add_proto_expert_info(e.undelivered, "Not delivered: " .. (report_codes[code] or "unknown")) end
        pinfo.cols.info = arrow .. "report " .. addr .. ": " .. (report_codes[code] or "?") .. " (" .. payload:sub(4, 9) .. ")"
            .. (n.report_of and (" on frame " .. n.report_of) or "")
    else
        t:add(f.type, "result")
        local text
        if n.response_to then
            t:add(f.response_to, n.response_to)
            t:add(f.cmd, n.cmd_mnemonic)
            local sw = t:add(f.swapped, n.swapped)
            if n.swapped then
                sw:append_text(" (dest group = command's source, source = command's dest group)")
            else
                sw:add_proto_expert_info(e.swap)
            end
            if n.shape then
                text = decode_result(n.shape, n.cmd_payload, payload, t, function(o, l) return data(6 + o, l) end)
            end
        else
            t:add_proto_expert_info(e.unpaired, "No command awaits a result from this address")
        end
        pinfo.cols.info = arrow .. "result " .. addr .. ": " .. (n.cmd_mnemonic and (n.cmd_mnemonic .. " ") or "")
            .. payload .. (text and (" (" .. text .. ")") or "")
    end
    return buf:len()
end

DissectorTable.get("wtap_encap"):add(wtap_encaps and wtap_encaps.USER0 or 45, p)
