// A minimal Foxglove WebSocket protocol client (subprotocol foxglove.websocket.v1, JSON channels):
// subscribes to every advertised channel and hands each message to onMessage(topic, object, timeNs).
// Can advertise one client channel and publish JSON on it (clientPublish capability).
const decoder = new TextDecoder();

export class Feed {
  constructor(url, { onMessage, onOpen, onClose, onStatus }) {
    this.url = url;
    this.onMessage = onMessage;
    this.onOpen = onOpen || (() => {});
    this.onClose = onClose || (() => {});
    this.onStatus = onStatus || (() => {});
    this.subs = new Map();      // subscription id -> topic
    this.nextSub = 1;
    this.clientChannels = new Map();  // topic -> client channel id
    this.received = 0;
    this.bytes = 0;
    // Flow control (godhand's "ack" op, feed.h): the viewer holds this page to a few dozen messages
    // sent and not yet handled, so a page starved of CPU draws the newest state, not a backlog.
    this.binaries = 0;
    this.acked = 0;
    this.ackAt = 0;
    setInterval(() => this.ack(true), 100);
    this.connect();
  }

  connect() {
    this.ws = new WebSocket(this.url, ['foxglove.websocket.v1']);
    this.ws.binaryType = 'arraybuffer';
    this.ws.onopen = () => this.onOpen();
    this.ws.onclose = () => {
      this.binaries = 0;
      this.acked = 0;
      this.subs.clear();
      this.clientChannels.clear();
      this.onClose();
      setTimeout(() => this.connect(), 1000);
    };
    this.ws.onmessage = (ev) => {
      if (typeof ev.data !== 'string') this.binaries++;
      this.handle(ev.data);
      this.ack(false);
    };
  }

  // Tells the viewer how many binary messages were handled: every 8, or after 50 ms (and from a
  // 100 ms timer, so that the last ones are acked when the feed goes quiet).
  ack(timer) {
    if (!this.ws || this.ws.readyState !== WebSocket.OPEN || this.binaries === this.acked) return;
    const now = performance.now();
    if (!timer && this.binaries - this.acked < 8 && now - this.ackAt < 50) return;
    this.ws.send(JSON.stringify({ op: 'ack', received: this.binaries }));
    this.acked = this.binaries;
    this.ackAt = now;
  }

  handle(data) {
    if (typeof data === 'string') {
      const m = JSON.parse(data);
      if (m.op === 'serverInfo') {
        this.sessionId = Number(m.sessionId);  // this connection's id in the viewer's stats
      } else if (m.op === 'advertise') {
        const subscriptions = [];
        for (const ch of m.channels) {
          if ([...this.subs.values()].includes(ch.topic)) continue;
          const id = this.nextSub++;
          this.subs.set(id, ch.topic);
          subscriptions.push({ id, channelId: ch.id });
        }
        if (subscriptions.length) this.ws.send(JSON.stringify({ op: 'subscribe', subscriptions }));
      } else if (m.op === 'status') {
        this.onStatus(m);
      }
      return;
    }
    const view = new DataView(data);
    if (view.byteLength < 13 || view.getUint8(0) !== 1) return;
    const sub = view.getUint32(1, true);
    const timeNs = view.getBigUint64(5, true);
    const topic = this.subs.get(sub);
    if (!topic) return;
    this.received++;
    this.bytes += view.byteLength;
    const text = decoder.decode(new Uint8Array(data, 13));
    this.onMessage(topic, JSON.parse(text), timeNs);
  }

  // Publishes `object` as JSON on `topic` (advertised on first use).
  publish(topic, object) {
    if (!this.ws || this.ws.readyState !== WebSocket.OPEN) return false;
    let id = this.clientChannels.get(topic);
    if (id === undefined) {
      id = this.clientChannels.size + 1;
      this.clientChannels.set(topic, id);
      this.ws.send(JSON.stringify({ op: 'advertise', channels: [{ id, topic, encoding: 'json', schemaName: topic }] }));
    }
    const payload = new TextEncoder().encode(JSON.stringify(object));
    const buf = new Uint8Array(5 + payload.length);
    buf[0] = 1;
    new DataView(buf.buffer).setUint32(1, id, true);
    buf.set(payload, 5);
    this.ws.send(buf);
    return true;
  }
}
