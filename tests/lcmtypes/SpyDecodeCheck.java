// Decodes every message on channels "SPYTEST_.*" the way lcm-spy does: the 8-byte fingerprint is looked up in
// lcm-spy's own type database (lcm.spy.LCMTypeDatabase, which scans the class path exactly like the GUI), and
// the message is decoded with the class found. Prints "decoded CHANNEL TYPE" per new channel, or
// "undecodable CHANNEL" when no type on the class path matches. Exits after the given number of seconds.
import java.io.DataInputStream;
import java.io.ByteArrayInputStream;
import java.util.HashSet;
import lcm.lcm.LCM;
import lcm.lcm.LCMDataInputStream;
import lcm.lcm.LCMSubscriber;
import lcm.spy.LCMTypeDatabase;

public class SpyDecodeCheck implements LCMSubscriber {
  private final LCMTypeDatabase database = new LCMTypeDatabase();
  private final HashSet<String> seen = new HashSet<>();

  public synchronized void messageReceived(LCM lcm, String channel, LCMDataInputStream ins) {
    if (seen.contains(channel)) return;
    try {
      byte[] bytes = new byte[ins.available()];
      ins.readFully(bytes);
      long fingerprint = new DataInputStream(new ByteArrayInputStream(bytes)).readLong();
      Class<?> type = database.getClassByFingerprint(fingerprint);
      if (type == null) {
        System.out.println("undecodable " + channel);
      } else {
        Object message = type.getConstructor(java.io.DataInput.class)
                             .newInstance(new DataInputStream(new ByteArrayInputStream(bytes)));
        System.out.println("decoded " + channel + " " + message.getClass().getName());
      }
      seen.add(channel);
    } catch (Exception e) {
      System.out.println("error " + channel + " " + e);
    }
    System.out.flush();
  }

  public static void main(String[] args) throws Exception {
    LCM lcm = new LCM(args[0]);
    lcm.subscribe("SPYTEST_.*", new SpyDecodeCheck());
    Thread.sleep(Long.parseLong(args[1]) * 1000);
    System.exit(0);
  }
}
