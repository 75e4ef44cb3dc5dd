// Decodes messages on channels "SPYTEST_.*" the way lcm-spy does: the 8-byte fingerprint is looked up in lcm-spy's
// own type database (lcm.spy.LCMTypeDatabase, which scans the class path exactly like the GUI), and the message is
// decoded with the class found. Prints "decoded CHANNEL TYPE" per new channel, or "undecodable CHANNEL" when no type
// on the class path matches.
//
//   SpyDecodeCheck URL SECONDS [CHANNEL...]   listen on the bus; print "listening" once subscribed; exit after
//                                             SECONDS, or as soon as every CHANNEL named has been decoded
//   SpyDecodeCheck --log FILE                 the first message of each channel of an LCM log file (lcm-logger's
//                                             format), read with LCM's own log reader
import java.io.ByteArrayInputStream;
import java.io.DataInputStream;
import java.io.EOFException;
import java.util.Arrays;
import java.util.HashSet;
import lcm.lcm.LCM;
import lcm.lcm.LCMDataInputStream;
import lcm.lcm.LCMSubscriber;
import lcm.logging.Log;
import lcm.spy.LCMTypeDatabase;

public class SpyDecodeCheck implements LCMSubscriber {
  private final LCMTypeDatabase database = new LCMTypeDatabase();
  private final HashSet<String> seen = new HashSet<>();
  private final HashSet<String> awaited = new HashSet<>();

  private synchronized void decode(String channel, byte[] bytes) {
    if (!channel.startsWith("SPYTEST_") || seen.contains(channel)) return;
    try {
      long fingerprint = new DataInputStream(new ByteArrayInputStream(bytes)).readLong();
      Class<?> type = database.getClassByFingerprint(fingerprint);
      if (type == null) {
        System.out.println("undecodable " + channel);
      } else {
        Object message = type.getConstructor(java.io.DataInput.class)
                             .newInstance(new DataInputStream(new ByteArrayInputStream(bytes)));
        System.out.println("decoded " + channel + " " + message.getClass().getName());
        awaited.remove(channel);
      }
      seen.add(channel);
    } catch (Exception e) {
      System.out.println("error " + channel + " " + e);
    }
    System.out.flush();
    notifyAll();
  }

  public void messageReceived(LCM lcm, String channel, LCMDataInputStream ins) {
    try {
      byte[] bytes = new byte[ins.available()];
      ins.readFully(bytes);
      decode(channel, bytes);
    } catch (Exception e) {
      System.out.println("error " + channel + " " + e);
      System.out.flush();
    }
  }

  public static void main(String[] args) throws Exception {
    SpyDecodeCheck check = new SpyDecodeCheck();
    if (args.length == 2 && args[0].equals("--log")) {
      Log log = new Log(args[1], "r");
      try {
        while (true) {
          Log.Event event = log.readNext();
          check.decode(event.channel, event.data);
        }
      } catch (EOFException end) {
        // the whole file was read
      }
      System.exit(0);
    }
    check.awaited.addAll(Arrays.asList(args).subList(2, args.length));
    LCM lcm = new LCM(args[0]);
    lcm.subscribe("SPYTEST_.*", check);
    System.out.println("listening");
    System.out.flush();
    long deadline = System.currentTimeMillis() + Long.parseLong(args[1]) * 1000;
    boolean untilAllDecoded = args.length > 2;
    synchronized (check) {
      for (long left = Long.parseLong(args[1]) * 1000; left > 0; left = deadline - System.currentTimeMillis()) {
        if (untilAllDecoded && check.awaited.isEmpty()) break;
        check.wait(left);
      }
    }
    System.exit(0);
  }
}
