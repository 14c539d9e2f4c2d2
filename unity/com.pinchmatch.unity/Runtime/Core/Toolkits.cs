// Data for the toolkits Unity developers already use, from a placed choice:
// - XR Interaction Toolkit: an attach pose at the pinch's centre, its forward (+Z) the direction the
//   hand moves in (against the approach), its right (+X) along the pinch line (thumb to index; a
//   tripod's thumb to the fingers' middle) made square to the forward;
// - HaRT (VirtualToRealConnection): virtual and real target pairs, best match first (HaRT reads only
//   the first);
// - HRTK: a VirtualTarget and a TrackedTarget pose per choice.
using System;
using System.Collections.Generic;

namespace Pinchmatch
{
    public struct TargetPair
    {
        /// <summary>Where the hand is seen to go (the virtual grasp's centre and attach rotation).</summary>
        public Pose Virtual;
        /// <summary>Where the real hand goes (on the tracked prop).</summary>
        public Pose Real;
        public double Cost;
    }

    public static class Toolkits
    {
        /// <summary>The attach pose of the fingertips <paramref name="tips"/> (thumb first) with the
        /// hand coming from <paramref name="approach"/> (null: from above, Unity's +Y).</summary>
        public static Pose Attach(Vec3[] tips, Vec3? approach)
        {
            var centre = Vec3.Centroid(tips);
            var fingers = tips.Length == 2 ? tips[1] : (tips[1] + tips[2]) * 0.5;
            var line = fingers - tips[0];
            var forward = -(approach ?? new Vec3(0, 1, 0)).Normalized;
            var right = line - forward * Vec3.Dot(line, forward);
            if (right.Length < 1e-9)  // the line along the approach: any square right
            {
                right = Vec3.Cross(new Vec3(0, 1, 0), forward);
                if (right.Length < 1e-9) right = Vec3.Cross(new Vec3(1, 0, 0), forward);
            }
            right = right.Normalized;
            var up = Vec3.Cross(forward, right);
            return new Pose(centre, Mat3.Columns(right, up, forward).ToQuat());
        }

        /// <summary>XRI's attach transform for the real fingertips on the prop.</summary>
        public static Pose XriAttach(Placed placed)
        {
            return Attach(placed.FingertipPositions, placed.Approach);
        }

        /// <summary>The virtual (seen) and real targets of one choice: the same for an object shown
        /// on the prop; the level's and the prop's for a redirected one. The seen side keeps the real
        /// approach (the warp moves the hand, never turns it).</summary>
        public static TargetPair Pair(Placed placed)
        {
            return new TargetPair
            {
                Virtual = Attach(placed.SeenFingertipPositions, placed.Approach),
                Real = Attach(placed.FingertipPositions, placed.Approach),
                Cost = placed.Cost,
            };
        }

        /// <summary>HaRT's pairs, cheapest first (ties in the given order).</summary>
        public static List<TargetPair> HartPairs(IEnumerable<Placed> placed)
        {
            var pairs = new List<TargetPair>();
            foreach (var p in placed) pairs.Add(Pair(p));
            var order = new List<int>();
            for (int i = 0; i < pairs.Count; i++) order.Add(i);
            order.Sort((a, b) => pairs[a].Cost != pairs[b].Cost ? pairs[a].Cost.CompareTo(pairs[b].Cost) : a.CompareTo(b));
            var sorted = new List<TargetPair>();
            foreach (int i in order) sorted.Add(pairs[i]);
            return sorted;
        }
    }
}
