// Generic cases for the core's tests: seeded random rotations, props turned about two axes and off
// the origin, both up conventions, pinch and tripod results written as pinchmatch writes them.
using System;
using System.Collections.Generic;
using Pinchmatch;

namespace Pinchmatch.Tests
{
    public static class Fixtures
    {
        public static readonly Vec3 ZUp = new Vec3(0, 0, 1), YUp = new Vec3(0, 1, 0);

        /// <summary>A uniformly random rotation (seeded).</summary>
        public static Quat RandomRotation(Random rng)
        {
            double u1 = rng.NextDouble(), u2 = rng.NextDouble(), u3 = rng.NextDouble();
            double a = Math.Sqrt(1 - u1), b = Math.Sqrt(u1);
            return new Quat(a * Math.Sin(2 * Math.PI * u2), a * Math.Cos(2 * Math.PI * u2),
                            b * Math.Sin(2 * Math.PI * u3), b * Math.Cos(2 * Math.PI * u3));
        }

        public static Vec3 RandomVec(Random rng, double scale)
        {
            return new Vec3((rng.NextDouble() * 2 - 1) * scale, (rng.NextDouble() * 2 - 1) * scale,
                            (rng.NextDouble() * 2 - 1) * scale);
        }

        /// <summary>A tracked prop turned about two axes, off the origin (Unity's world, metres).</summary>
        public static Pose TurnedProp(double aDeg, double bDeg)
        {
            var q = Quat.AxisAngle(new Vec3(0, 1, 0), aDeg) * Quat.AxisAngle(new Vec3(1, 0, 0), bDeg);
            return new Pose(new Vec3(0.42, 0.87, -0.31), q.Normalized);
        }

        public static Dictionary<string, object> Obj(params object[] kv)
        {
            var d = new Dictionary<string, object>();
            for (int i = 0; i < kv.Length; i += 2) d[(string)kv[i]] = kv[i + 1];
            return d;
        }

        public static List<object> L(params object[] items) { return new List<object>(items); }

        public static List<object> V(Vec3 v) { return L(v.X, v.Y, v.Z); }

        /// <summary>A result of one prop and one virtual object: the grasp's contacts on the prop
        /// (mm, its file frame, up <paramref name="propUp"/>), normals pointing away from their
        /// middle, and the registration (rotation r, translation t): the virtual contacts are the
        /// prop's taken back by it, so that the fingers meet.</summary>
        public static string Result(Vec3 propUp, Vec3[] contacts, Quat r, Vec3 t, string placement = "registered",
                                    double cost = 0.5, bool withAlternative = false)
        {
            var match = Choice(contacts, r, t, cost);
            match["virtual"] = "mug";
            match["noticeable"] = false;
            match["reason"] = null;
            match["alternatives"] = withAlternative
                ? L(Choice(Shift(contacts, new Vec3(3, -2, 5)), r, t, cost + 0.25)) : L();
            return Json.Write(Obj(
                "schema", "pinchmatch.matches/1",
                "settings", Obj("fingertip_radius_mm", 8.0, "placement", placement),
                "grasp", contacts.Length == 3 ? "tripod" : "pinch",
                "tangibles", L(Obj("name", "prop", "node", null, "up_vector", V(propUp))),
                "virtuals", L(Obj("name", "mug", "node", null, "up_vector", V(ZUp))),
                "matches", L(match)));
        }

        public static Vec3[] Shift(Vec3[] points, Vec3 d)
        {
            var out_ = new Vec3[points.Length];
            for (int i = 0; i < points.Length; i++) out_[i] = points[i] + d;
            return out_;
        }

        public static Vec3[] Normals(Vec3[] contacts)
        {
            var mid = Vec3.Centroid(contacts);
            var n = new Vec3[contacts.Length];
            for (int i = 0; i < n.Length; i++) n[i] = (contacts[i] - mid).Normalized;
            return n;
        }

        public static Dictionary<string, object> Choice(Vec3[] contacts, Quat r, Vec3 t, double cost)
        {
            var R = Mat3.Of(r);
            var back = R.Transposed;
            var virtualContacts = new Vec3[contacts.Length];
            for (int i = 0; i < contacts.Length; i++) virtualContacts[i] = back.Apply(contacts[i] - t);
            var rows = L(L(R.M00, R.M01, R.M02, t.X), L(R.M10, R.M11, R.M12, t.Y), L(R.M20, R.M21, R.M22, t.Z),
                         L(0.0, 0.0, 0.0, 1.0));
            return Obj("tangible", "prop", "cost", cost,
                       "tangible_pose", Pose(contacts, new Vec3(0.3, 0.2, 0.93).Normalized),
                       "virtual_pose", Pose(virtualContacts, back.Apply(new Vec3(0.3, 0.2, 0.93).Normalized)),
                       "transform_virtual_to_tangible", rows);
        }

        static Dictionary<string, object> Pose(Vec3[] contacts, Vec3 approach)
        {
            var normals = Normals(contacts);
            if (contacts.Length == 3)
            {
                var cs = L();
                var ns = L();
                for (int i = 0; i < 3; i++) { cs.Add(V(contacts[i])); ns.Add(V(normals[i])); }
                return Obj("contacts_mm", cs, "normals", ns, "approach", V(approach));
            }
            return Obj("p1_mm", V(contacts[0]), "p2_mm", V(contacts[1]), "n1", V(normals[0]), "n2", V(normals[1]),
                       "approach", V(approach));
        }

        public static readonly Vec3[] Pinch = { new Vec3(31, -4, 42), new Vec3(-25, 6, 40) };

        public static readonly Vec3[] Tripod = { new Vec3(30, 0, 50), new Vec3(-20, 18, 52), new Vec3(-18, -21, 49) };

        public static void Near(Vec3 expected, Vec3 actual, double tolerance, string what = "")
        {
            double d = (expected - actual).Length;
            if (!(d <= tolerance))
                throw new NUnit.Framework.AssertionException(what + " expected " + expected + " got " + actual + " (off by " + d + ")");
        }
    }
}
