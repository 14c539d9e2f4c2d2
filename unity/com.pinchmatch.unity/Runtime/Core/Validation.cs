// Is the grasp on its targets? The method's study: every fingertip within 5 mm of its target and the
// grasp's direction within 14 degrees of the target's, held for 1 s (xr_core.js: checkPinch,
// checkGrasp, HoldTimer). Positions in metres, reports in mm and degrees.
using System;

namespace Pinchmatch
{
    public struct Limits
    {
        public double PosMm, AngleDeg, HoldS;

        public Limits(double posMm, double angleDeg, double holdS) { PosMm = posMm; AngleDeg = angleDeg; HoldS = holdS; }

        public static readonly Limits Study = new Limits(5, 14, 1);
    }

    public struct GraspCheck
    {
        public bool Ok;
        /// <summary>Which finger order was judged (the one with the smaller worst error).</summary>
        public string Order;
        /// <summary>Per finger (thumb, index, middle), the distance to its target, mm.</summary>
        public double[] ErrorsMm;
        public double AngleErrorDeg;
    }

    public static class Validation
    {
        /// <summary>A pinch (two targets): either finger may go to either target; the direction
        /// compared is thumb to index against the targets'. A tripod (three: the thumb's, then the
        /// index's and middle's in either order): the direction from the thumb to the fingers'
        /// middle. <paramref name="tips"/>: thumb, index (and middle) in metres.</summary>
        public static GraspCheck Check(Vec3[] tips, Vec3[] targets, Limits limits)
        {
            if (targets.Length != 2 && targets.Length != 3)
                throw new ArgumentException("a grasp has 2 or 3 targets, not " + targets.Length);
            if (tips.Length < targets.Length)
                throw new ArgumentException("the grasp needs " + targets.Length + " fingertips");
            GraspCheck a, b;
            if (targets.Length == 2)
            {
                a = Pinch(tips, targets[0], targets[1], "thumb on p1");
                b = Pinch(tips, targets[1], targets[0], "thumb on p2");
            }
            else
            {
                a = Tripod(tips, targets[0], targets[1], targets[2], "index on the second target");
                b = Tripod(tips, targets[0], targets[2], targets[1], "index on the third target");
            }
            var best = Max(a.ErrorsMm) <= Max(b.ErrorsMm) ? a : b;
            best.Ok = Max(best.ErrorsMm) <= limits.PosMm && best.AngleErrorDeg <= limits.AngleDeg;
            return best;
        }

        static GraspCheck Pinch(Vec3[] tips, Vec3 a, Vec3 b, string name)
        {
            return new GraspCheck
            {
                Order = name,
                ErrorsMm = new[] { (tips[0] - a).Length * 1000, (tips[1] - b).Length * 1000 },
                AngleErrorDeg = Vec3.AngleDeg(tips[1] - tips[0], b - a),
            };
        }

        static GraspCheck Tripod(Vec3[] tips, Vec3 t0, Vec3 a, Vec3 b, string name)
        {
            var fingers = (tips[1] + tips[2]) * 0.5;
            return new GraspCheck
            {
                Order = name,
                ErrorsMm = new[] { (tips[0] - t0).Length * 1000, (tips[1] - a).Length * 1000,
                                   (tips[2] - b).Length * 1000 },
                AngleErrorDeg = Vec3.AngleDeg(fingers - tips[0], (a + b) * 0.5 - t0),
            };
        }

        static double Max(double[] values)
        {
            double m = double.NegativeInfinity;
            foreach (var v in values) m = Math.Max(m, v);
            return m;
        }
    }

    /// <summary>A grasp is validated once it has been on target for HoldS without a break; it stays
    /// validated until reset.</summary>
    public sealed class HoldTimer
    {
        readonly double holdS;
        double? since;

        public HoldTimer(double holdS) { this.holdS = holdS; }

        public bool Validated { get; private set; }

        public void Reset() { since = null; Validated = false; }

        /// <summary>On target or not at time t (seconds, increasing); the seconds held so far.</summary>
        public double Update(bool ok, double t)
        {
            if (Validated) return holdS;
            if (!ok) { since = null; return 0; }
            if (!since.HasValue) since = t;
            double held = t - since.Value;
            if (held >= holdS) Validated = true;
            return held;
        }
    }
}
