using System;
using System.Linq;
using NUnit.Framework;
using Pinchmatch;

namespace Pinchmatch.Tests
{
    /// <summary>Placements checked by what they mean: the virtual object's contacts, seen where the
    /// placement puts it, meet the prop's contacts where the tracked prop stands.</summary>
    [TestFixture]
    public class PlacementTests
    {
        static MatchesFile Result(Vec3 up, Vec3[] contacts, int seed, bool alternative = false)
        {
            var rng = new Random(seed);
            return MatchesFile.Parse(Fixtures.Result(up, contacts, Fixtures.RandomRotation(rng),
                                                     Fixtures.RandomVec(rng, 60), withAlternative: alternative));
        }

        [TestCase(0, 35.0, -70.0, 2)]
        [TestCase(1, 35.0, -70.0, 2)]
        [TestCase(0, -120.0, 20.0, 3)]
        [TestCase(1, -120.0, 20.0, 3)]
        public void TheVirtualContactsMeetTheProps(int upCase, double a, double b, int fingers)
        {
            var up = upCase == 0 ? Fixtures.ZUp : Fixtures.YUp;
            var file = Result(up, fingers == 2 ? Fixtures.Pinch : Fixtures.Tripod, 10 + fingers);
            var m = file.Matches[0];
            var prop = Fixtures.TurnedProp(a, b);
            var placed = Placement.OnSceneProp(file, m, m.Best, prop);
            var B = Frames.FileMmToUnity(up);  // the scene bakes the virtual with the prop's map
            for (int i = 0; i < fingers; i++)
            {
                var seen = placed.VirtualPose.Point(B.Point(m.Best.OnVirtual.ContactsMm[i]));
                var onProp = prop.Point(B.Point(m.Best.OnTangible.ContactsMm[i]));
                Fixtures.Near(onProp, seen, 1e-9, "contact " + i);
            }
            Assert.AreEqual(1.0, placed.VirtualPose.Rotation.Norm, 1e-12);
        }

        [TestCase(0)]
        [TestCase(1)]
        public void FingertipsAreThePadsOneRadiusOffTheContacts(int upCase)
        {
            var up = upCase == 0 ? Fixtures.ZUp : Fixtures.YUp;
            var file = Result(up, Fixtures.Tripod, 4);
            var m = file.Matches[0];
            var prop = Fixtures.TurnedProp(50, 25);
            var placed = Placement.OnSceneProp(file, m, m.Best, prop);
            var B = Frames.FileMmToUnity(up);
            CollectionAssert.AreEqual(new[] { Joints.ThumbTip, Joints.IndexTip, Joints.MiddleTip },
                                      placed.Fingertips.Select(t => t.Joint).ToArray());
            for (int i = 0; i < 3; i++)
            {
                var contact = prop.Point(B.Point(m.Best.OnTangible.ContactsMm[i]));
                Assert.AreEqual(0.008, (placed.Fingertips[i].Position - contact).Length, 1e-12);
                var outward = prop.Rotation * Frames.FileDirectionToUnity(up, m.Best.OnTangible.Normals[i]);
                Fixtures.Near(contact + outward * 0.008, placed.Fingertips[i].Position, 1e-12);
            }
        }

        [Test]
        public void TheApproachKeepsItsAnglesToTheGrasp()
        {
            var file = Result(Fixtures.ZUp, Fixtures.Pinch, 5);
            var m = file.Matches[0];
            var placed = Placement.OnSceneProp(file, m, m.Best, Fixtures.TurnedProp(-30, 80));
            var g = m.Best.OnTangible;
            double inFile = Vec3.AngleDeg(g.Approach.Value, g.ContactsMm[1] - g.ContactsMm[0]);
            var tips = placed.FingertipPositions;
            double inUnity = Vec3.AngleDeg(placed.Approach.Value, tips[1] - tips[0]);
            Assert.AreEqual(inFile, inUnity, 1e-9);
            Assert.AreEqual(1.0, placed.Approach.Value.Length, 1e-12);
        }

        [Test]
        public void MovingThePropMovesEverythingWithIt()
        {
            var file = Result(Fixtures.YUp, Fixtures.Tripod, 6);
            var m = file.Matches[0];
            var first = Fixtures.TurnedProp(10, 20);
            var move = new Pose(new Vec3(-1.5, 0.1, 2.2), Quat.AxisAngle(new Vec3(0.2, 1, -0.4), 73));
            var a = Placement.OnSceneProp(file, m, m.Best, first);
            var b = Placement.OnSceneProp(file, m, m.Best, move * first);
            Fixtures.Near(move.Point(a.VirtualPose.Position), b.VirtualPose.Position, 1e-12);
            Assert.Less(Quat.AngleDeg(move.Rotation * a.VirtualPose.Rotation, b.VirtualPose.Rotation), 1e-9);
            for (int i = 0; i < 3; i++)
                Fixtures.Near(move.Point(a.Fingertips[i].Position), b.Fingertips[i].Position, 1e-12);
        }

        [Test]
        public void TheCentreAndTheWristLieOnTheApproach()
        {
            var file = Result(Fixtures.ZUp, Fixtures.Pinch, 8);
            var m = file.Matches[0];
            var prop = Fixtures.TurnedProp(15, -45);
            var placed = Placement.OnSceneProp(file, m, m.Best, prop);
            var B = Frames.FileMmToUnity(Fixtures.ZUp);
            Fixtures.Near(prop.Point(B.Point(m.Best.OnTangible.CenterMm)), placed.PinchCenter, 1e-12);
            var wrist = Placement.Wrist(placed).Value;
            Assert.AreEqual(0.110, (wrist - placed.PinchCenter).Length, 1e-12);
            Assert.AreEqual(0.0, Vec3.AngleDeg(wrist - placed.PinchCenter, placed.Approach.Value), 1e-6);
        }

        [Test]
        public void AtTheOriginAZUpPropsThumbIsWhereTheSceneHasIt()
        {
            var file = MatchesFile.Parse(Fixtures.Result(Fixtures.ZUp, Fixtures.Pinch, Quat.Identity, Vec3.Zero));
            var m = file.Matches[0];
            var placed = Placement.OnSceneProp(file, m, m.Best, Pose.Identity);
            // thumb contact (31, -4, 42) mm, normal along the pinch line; glTF (x, z, -y) m, Unity -x
            var n = m.Best.OnTangible.Normals[0];
            var pad = new Vec3(31, -4, 42) + n * 8;
            Fixtures.Near(new Vec3(-pad.X, pad.Z, -pad.Y) / 1000, placed.Fingertips[0].Position, 1e-15);
            Fixtures.Near(Vec3.Zero, placed.VirtualPose.Position, 1e-15);
        }

        [Test]
        public void AlternativesArePlacedAlike()
        {
            var file = Result(Fixtures.ZUp, Fixtures.Pinch, 9, alternative: true);
            var m = file.Matches[0];
            Assert.AreEqual(2, m.Choices.Count());
            var alt = Placement.OnSceneProp(file, m, m.Alternatives[0], Fixtures.TurnedProp(5, 5));
            Assert.AreEqual(0.75, alt.Cost, 1e-12);
            var B = Frames.FileMmToUnity(Fixtures.ZUp);
            var seen = alt.VirtualPose.Point(B.Point(m.Alternatives[0].OnVirtual.ContactsMm[0]));
            Fixtures.Near(Fixtures.TurnedProp(5, 5).Point(B.Point(m.Alternatives[0].OnTangible.ContactsMm[0])), seen, 1e-9);
        }

        [Test]
        public void AMatchWithoutAPropKeepsItsReason()
        {
            var text = Json.Write(Fixtures.Obj(
                "schema", "pinchmatch.matches/1", "settings", Fixtures.Obj("fingertip_radius_mm", 8.0),
                "tangibles", Fixtures.L(), "virtuals", Fixtures.L(),
                "matches", Fixtures.L(Fixtures.Obj("virtual", "cup", "tangible", null, "reason", "every tangible serves another"))));
            var m = MatchesFile.Parse(text).Matches[0];
            Assert.IsNull(m.Best);
            Assert.AreEqual("every tangible serves another", m.Reason);
            Assert.AreEqual(0, m.Choices.Count());
        }

        [Test]
        public void AFileOfAnotherKindIsNamed()
        {
            var e = Assert.Throws<JsonException>(() => MatchesFile.Parse("{\"schema\": \"pinchmatch.study/1\"}"));
            StringAssert.Contains("pinchmatch.matches/1", e.Message);
            var f = Assert.Throws<JsonException>(() => MatchesFile.Parse(
                "{\"schema\": \"pinchmatch.matches/1\", \"settings\": {}}"));
            StringAssert.Contains("fingertip_radius_mm", f.Message);
        }
    }
}
