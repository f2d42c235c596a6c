// The npm `visca-over-ip` package (tests/visca/package.json) against
// gimbal-visca. The package's own camera (`ViscaCamera`) speaks raw VISCA
// on UDP, as PTZOptics cameras take it; for raw VISCA over TCP (PTZOptics'
// port 5678, Companion's PTZOptics module) its messages and reply parser
// (`ViscaCommand`) go over a TCP connection of node's own.
//
//   node tcp.js tcp PORT   pan left, stop, absolute position (200, 100), over TCP
//   node tcp.js udp HOST PORT   Home through the package's ViscaCamera
//
// Prints one JSON line: the replies each command got, as the package read them.

const net = require('net');
const { ViscaCamera, ViscaCommand } = require('visca-over-ip');

const GUARD_MS = 60000;

function out(value) {
  console.log(JSON.stringify(value));
}

function overTcp(port) {
  const socket = net.connect(port, '127.0.0.1');
  const steps = [
    ['left', ViscaCommand.cameraPanTilt(-8, 0)],
    ['stop', ViscaCommand.cameraPanTilt(0, 0)],
    ['absolute', ViscaCommand.cameraPanTiltDirect(0x18, 0x14, 200, 100)],
  ];
  const replies = {};
  let step = 0;
  let pending = Buffer.alloc(0);
  const send = () => {
    if (step === steps.length) {
      out(replies);
      socket.end();
      process.exit(0);
    }
    const [name, command] = steps[step];
    replies[name] = [];
    socket.write(Buffer.from(command.toPacket()));
  };
  socket.on('connect', send);
  socket.on('data', (data) => {
    pending = Buffer.concat([pending, data]);
    let end;
    while ((end = pending.indexOf(0xff)) >= 0) {
      const reply = ViscaCommand.fromPacket([...pending.subarray(0, end + 1)]);
      pending = pending.subarray(end + 1);
      const [name] = steps[step];
      replies[name].push({ type: reply.messageType, socket: reply.socket, data: reply.data });
      // 0x40 ACK: the Completion (0x50) or an error (0x60) follows.
      if (reply.messageType !== 0x40) {
        step += 1;
        // Let the left drive run a little before its stop.
        setTimeout(send, name === 'left' ? 700 : 0);
      }
    }
  });
  socket.on('error', (e) => {
    out({ error: String(e) });
    process.exit(1);
  });
}

function overUdp(host, port) {
  const camera = new ViscaCamera(host, port);
  const command = ViscaCommand.cameraPanTiltHome();
  const seen = [];
  command.on('ack', () => seen.push('ack'));
  command.on('complete', () => {
    seen.push('complete');
    out({ home: seen });
    process.exit(0);
  });
  command.on('error', (e) => {
    out({ home: seen, error: String(e) });
    process.exit(0);
  });
  // Its socket connects asynchronously; it sends only once connected.
  camera.client.once('connect', () => camera.sendCommand(command));
}

setTimeout(() => {
  out({ error: 'no answer within the hang guard' });
  process.exit(1);
}, GUARD_MS);

const [mode, a, b] = process.argv.slice(2);
if (mode === 'tcp') {
  overTcp(Number(a));
} else {
  overUdp(a, Number(b));
}
