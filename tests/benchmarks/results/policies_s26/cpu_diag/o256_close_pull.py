import json, numpy as np
T = json.load(open("/tmp/s26/diag_o256/traj.json"))
print("# o256 (open_drawer, joints), kitchen 101: close = first frame whose gripper command > 0.5; pull = first frame after it with base_vx < -0.02;")
print("# gripper opening (environment state's last entry, m) at close, pull and 15 frames into the pull; end effector minus handle at the pull (base frame, m)")
for t in sorted(T, key=lambda t: t["rec"]["seed"]):
    A = np.array(t["actions"]); n = t["action_names"]; vx = A[:, n.index("base_vx")]; g = A[:, n.index("gripper")]
    E = np.array([x[2] for x in t["log"]]); S = np.array([x[1] for x in t["log"]]); sn = t["state_names"]
    ee = S[:, [sn.index(c) for c in ("ee_x","ee_y","ee_z")]]
    c = int(np.argmax(g > 0.5)); p = c + int(np.argmax(vx[c:] < -0.02))
    print(t["rec"]["seed"], "ok " if t["rec"]["success"] else "BAD", "close", c, "pull", p, "gap", p - c,
          "opening@close %.3f @pull %.3f @pull+15 %.3f" % (E[c, -1], E[p, -1], E[min(p+15, len(E)-1), -1]),
          "ee-handle@pull", np.round(ee[p] - E[p, :3], 3), "min base_vx in 3 s after close %+.3f" % vx[c:c+90].min())
