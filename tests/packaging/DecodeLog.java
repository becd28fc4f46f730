// java DecodeLog LOG MANIFEST TYPE...: reads the LCM log LOG with
// lcm.logging.Log and decodes every event as lcm-spy does: the class is found
// by the message's fingerprint in lcm.spy.LCMTypeDatabase (the LCM types on
// the class path: sweptccd_msgs.jar). Fails (exit 1) unless
//  - the class is sweptccd.<type> where MANIFEST says "CHANNEL TYPE",
//  - the message decodes and re-encodes to exactly the logged bytes,
//  - every field holds a value other than its default (non-zero numbers, true
//    booleans, non-empty strings and arrays, byte arrays not all zero,
//    recursively), as written by
//    tests/packaging/lcm_log_writer.cc,
//  - every MANIFEST line was seen once, and every TYPE (one per msgs/*.lcm
//    file, from java_decode_test.sh) is among them.
import java.io.BufferedReader;
import java.io.ByteArrayOutputStream;
import java.io.DataInputStream;
import java.io.ByteArrayInputStream;
import java.io.DataOutputStream;
import java.io.EOFException;
import java.io.FileReader;
import java.lang.reflect.Array;
import java.lang.reflect.Field;
import java.lang.reflect.Modifier;
import java.util.ArrayList;
import java.util.Arrays;
import java.util.LinkedHashMap;
import java.util.List;
import java.util.Map;
import java.util.TreeSet;

import lcm.lcm.LCMEncodable;
import lcm.logging.Log;
import lcm.spy.LCMTypeDatabase;

public class DecodeLog {
  static List<String> errors = new ArrayList<>();

  static void fail(String what) {
    errors.add(what);
    System.err.println("DecodeLog: " + what);
  }

  // Every public instance field of an LCM object holds a non-default value.
  static void checkSet(Object value, String path) throws IllegalAccessException {
    if (value == null) {
      fail(path + " is null");
    } else if (value instanceof byte[]) {  // e.g. mac[32]: an HMAC may hold zero bytes
      boolean any = false;
      for (byte b : (byte[]) value) any |= b != 0;
      if (!any) fail(path + " is all zero");
    } else if (value.getClass().isArray()) {
      int n = Array.getLength(value);
      if (n == 0) fail(path + " is an empty array");
      for (int i = 0; i < n; i++) checkSet(Array.get(value, i), path + "[" + i + "]");
    } else if (value instanceof String) {
      if (((String) value).isEmpty()) fail(path + " is an empty string");
    } else if (value instanceof Boolean) {
      if (!(Boolean) value) fail(path + " is false");
    } else if (value instanceof Number) {
      if (((Number) value).doubleValue() == 0.0) fail(path + " is 0");
    } else if (value instanceof LCMEncodable) {
      for (Field f : value.getClass().getFields()) {
        if (Modifier.isStatic(f.getModifiers())) continue;
        checkSet(f.get(value), path + "." + f.getName());
      }
    } else {
      fail(path + " has unexpected class " + value.getClass().getName());
    }
  }

  public static void main(String[] args) throws Exception {
    if (args.length < 3) {
      System.err.println("usage: java DecodeLog LOG MANIFEST TYPE...");
      System.exit(2);
    }
    Map<String, String> expected = new LinkedHashMap<>();
    try (BufferedReader in = new BufferedReader(new FileReader(args[1]))) {
      for (String line; (line = in.readLine()) != null; ) {
        String[] parts = line.trim().split(" ");
        if (parts.length != 2) throw new IllegalStateException("bad manifest line: " + line);
        expected.put(parts[0], parts[1]);
      }
    }
    TreeSet<String> manifestTypes = new TreeSet<>(expected.values());
    for (int i = 2; i < args.length; i++) {
      if (!manifestTypes.contains(args[i])) {
        fail("type " + args[i] + " (msgs/" + args[i] + ".lcm) was not written: add it to "
             + "SWEPTCCD_LCM_TYPES in msgs/CMakeLists.txt");
      }
    }

    LCMTypeDatabase types = new LCMTypeDatabase();  // lcm-spy's class lookup
    Log log = new Log(args[0], "r");
    Map<String, Integer> seen = new LinkedHashMap<>();
    TreeSet<String> decodedTypes = new TreeSet<>();
    while (true) {
      Log.Event event;
      try {
        event = log.readNext();
      } catch (EOFException end) {
        break;
      }
      seen.merge(event.channel, 1, Integer::sum);
      String type = expected.get(event.channel);
      if (type == null) {
        fail("channel " + event.channel + " is not in the manifest");
        continue;
      }
      long fingerprint = new DataInputStream(new ByteArrayInputStream(event.data)).readLong();
      Class<?> cls = types.getClassByFingerprint(fingerprint);
      if (cls == null) {
        fail(event.channel + ": lcm-spy finds no class for fingerprint 0x"
             + Long.toHexString(fingerprint) + " (is " + type + " in sweptccd_msgs.jar?)");
        continue;
      }
      if (!cls.getName().equals("sweptccd." + type)) {
        fail(event.channel + ": fingerprint names " + cls.getName() + ", expected sweptccd." + type);
        continue;
      }
      LCMEncodable msg = (LCMEncodable) cls.getConstructor(byte[].class).newInstance(event.data);
      ByteArrayOutputStream bytes = new ByteArrayOutputStream();
      msg.encode(new DataOutputStream(bytes));
      if (!Arrays.equals(bytes.toByteArray(), event.data)) {
        fail(event.channel + ": " + type + " re-encoded differs from the logged bytes ("
             + bytes.size() + " vs " + event.data.length + " bytes)");
      }
      int before = errors.size();
      checkSet(msg, type);
      if (errors.size() > before) {
        fail(type + " has default-valued fields: give it a Fill() in "
             + "tests/packaging/lcm_log_writer.cc");
      }
      decodedTypes.add(type);
      System.out.println("decoded " + event.channel + " as " + cls.getName() + " ("
                         + event.data.length + " bytes)");
    }
    log.close();
    for (String channel : expected.keySet()) {
      Integer n = seen.get(channel);
      if (n == null || n != 1) {
        fail("channel " + channel + " seen " + (n == null ? 0 : n) + " times, expected once");
      }
    }
    if (!errors.isEmpty()) {
      System.err.println("DecodeLog: " + errors.size() + " problem(s)");
      System.exit(1);
    }
    System.out.println("DecodeLog: " + seen.size() + " channels, " + decodedTypes.size()
                       + " types decoded: " + decodedTypes);
  }
}
