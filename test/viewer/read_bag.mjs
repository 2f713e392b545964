// Reads an MCAP file as Foxglove does (@mcap/core's indexed reader, @foxglove/rosmsg's parser of the
// schemas stored in the file, @foxglove/rosmsg2-serialization's CDR reader) and prints, as JSON, for every
// topic its schema, the number of messages and how many decoded; with the decoded messages of the topics
// named after the file ("all" for every topic) so that a test can compare them with another reader.
//   node read_bag.mjs FILE.mcap [TOPIC ...]
import { readFile } from "node:fs/promises";
import { McapIndexedReader } from "@mcap/core";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";

const [file, ...wanted] = process.argv.slice(2);
const bytes = await readFile(file);
const readable = {
  size: async () => BigInt(bytes.byteLength),
  read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
};
const reader = await McapIndexedReader.Initialize({ readable });
const decoders = new Map();
const topics = {};
for (const channel of reader.channelsById.values()) {
  const schema = reader.schemasById.get(channel.schemaId);
  topics[channel.topic] = { schema: schema.name, schemaEncoding: schema.encoding, messageEncoding: channel.messageEncoding,
    messages: 0, decoded: 0, errors: [], values: [] };
  const definition = parse(new TextDecoder().decode(schema.data), { ros2: true });
  decoders.set(channel.id, new MessageReader(definition));
}
for await (const message of reader.readMessages()) {
  const topic = topics[reader.channelsById.get(message.channelId).topic];
  topic.messages += 1;
  try {
    const value = decoders.get(message.channelId).readMessage(message.data);
    topic.decoded += 1;
    if (wanted.includes("all") || wanted.includes(reader.channelsById.get(message.channelId).topic)) {
      topic.values.push({ logTime: message.logTime, message: value });
    }
  } catch (error) {
    if (topic.errors.length < 5) topic.errors.push(String(error));
  }
}
// JSON has no NaN or infinity: those are printed as the strings "NaN", "Infinity", "-Infinity".
const plain = (_, v) => (typeof v === "bigint" ? Number(v) : ArrayBuffer.isView(v) ? Array.from(v)
  : typeof v === "number" && !Number.isFinite(v) ? String(v) : v);
process.stdout.write(JSON.stringify({ topics }, plain));
