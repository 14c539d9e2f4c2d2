using System;
using System.Collections.Generic;
using System.Linq;
using NUnit.Framework;
using Pinchmatch;

namespace Pinchmatch.Tests
{
    [TestFixture]
    public class WarpTests
    {
        static readonly Vec3 Start = new Vec3(-0.5, 1.05, 0.05), Physical = new Vec3(0.12, 0.80, -0.19),
                             Virtual = new Vec3(-0.47, 0.93, -0.23);

        [Test]
        public void TheRatioRunsFromTheStartToTheTargetClamped()
        {
            Assert.AreEqual(0.0, Warp.Ratio(Start, Physical, Start));
            Assert.AreEqual(1.0, Warp.Ratio(Start, Physical, Physical));
            Assert.AreEqual(0.25, Warp.Ratio(Start, Physical, Start + (Physical - Start) * 0.25), 1e-12);
            Assert.AreEqual(0.0, Warp.Ratio(Start, Physical, Start - (Physical - Start)));
            Assert.AreEqual(1.0, Warp.Ratio(Start, Physical, Physical + (Physical - Start)));
            Assert.AreEqual(1.0, Warp.Ratio(Start, Start, Physical));
        }

        [Test]
        public void TheSeenHandReachesTheVirtualGraspWhenTheRealOneReachesTheProp()
        {
            var real = new[] { Physical + new Vec3(0.02, 0, 0), Physical - new Vec3(0.02, 0, 0) };
            var seen = Warp.Fingertips(Start, Physical, Virtual, real);
            Fixtures.Near(Virtual + new Vec3(0.02, 0, 0), seen[0], 1e-12);
            Fixtures.Near(Virtual - new Vec3(0.02, 0, 0), seen[1], 1e-12);
        }

        [Test]
        public void AlongThePathTheOffsetGrowsInProportion()
        {
            for (double a = 0; a <= 1.0; a += 0.125)
            {
                var h = Start + (Physical - Start) * a;
                Fixtures.Near((Virtual - Physical) * a, Warp.Offset(Start, Physical, Virtual, h), 1e-12);
            }
        }

        [Test]
        public void TheWarpIsTheSameInGltfsFrameAndInUnitys()
        {
            var rng = new Random(21);
            for (int k = 0; k < 20; k++)
            {
                var h = Start + Fixtures.RandomVec(rng, 0.4);
                var inGltf = Warp.Offset(Frames.UnityToGltf(Start), Frames.UnityToGltf(Physical),
                                         Frames.UnityToGltf(Virtual), Frames.UnityToGltf(h));
                Fixtures.Near(Frames.GltfToUnity(inGltf), Warp.Offset(Start, Physical, Virtual, h), 1e-15);
            }
        }

        [Test]
        public void ATripodIsWarpedAtItsFingertipsCentroid()
        {
            var real = new[] { new Vec3(0, 0.9, 0), new Vec3(0.03, 0.9, 0.01), new Vec3(0.03, 0.88, -0.02) };
            var seen = Warp.Fingertips(Start, Physical, Virtual, real);
            var d = Warp.Offset(Start, Physical, Virtual, Vec3.Centroid(real));
            for (int i = 0; i < 3; i++) Fixtures.Near(real[i] + d, seen[i], 1e-15);
        }

        [Test]
        public void AnObjectOnThePropIsNotWarped()
        {
            var placed = new Placed { Mode = "carousel", HandStart = Start, PhysicalTarget = Physical, VirtualTarget = Virtual };
            var real = new[] { new Vec3(0.1, 0.9, 0), new Vec3(0.13, 0.9, 0.01) };
            var seen = Warp.Fingertips(placed, real);
            Assert.AreNotSame(real, seen);
            CollectionAssert.AreEqual(real, seen);
        }
    }

    [TestFixture]
    public class CarouselTests
    {
        static MatchesFile File(params string[] modes)
        {
            var matches = Fixtures.L();
            for (int i = 0; i < modes.Length; i++)
            {
                var m = Fixtures.Choice(Fixtures.Pinch, Quat.Identity, Vec3.Zero, 0.1 * i);
                m["virtual"] = "v" + i;
                m["tangible"] = i % 2 == 0 ? "a" : "b";
                m["redirection"] = Fixtures.Obj("mode", modes[i], "hand_start_mm", Fixtures.L(0.0, 0.0, 0.0),
                                                "physical_target_mm", Fixtures.L(0.0, 0.0, 0.0),
                                                "virtual_target_mm", Fixtures.L(0.0, 0.0, 0.0));
                matches.Add(m);
            }
            return MatchesFile.Parse(Json.Write(Fixtures.Obj(
                "schema", "pinchmatch.matches/1", "settings", Fixtures.Obj("fingertip_radius_mm", 8.0),
                "tangibles", Fixtures.L(Fixtures.Obj("name", "a", "up_vector", Fixtures.V(Fixtures.ZUp)),
                                        Fixtures.Obj("name", "b", "up_vector", Fixtures.V(Fixtures.ZUp))),
                "virtuals", Fixtures.L(), "matches", matches)));
        }

        [Test]
        public void TheQueueHoldsThePropsCarouselObjectsInOrder()
        {
            var file = File("carousel", "carousel", "redirect", "carousel", "carousel");
            CollectionAssert.AreEqual(new[] { 0, 4 }, Carousel.Queue(file, "a"));
            CollectionAssert.AreEqual(new[] { 1, 3 }, Carousel.Queue(file, "b"));
            CollectionAssert.AreEqual(new[] { 0, 1, 3, 4 }, Carousel.Queue(file, null));
        }

        [Test]
        public void EachTurnBringsTheNextObjectRoundAgain()
        {
            var c = new Carousel(File("carousel", "redirect", "carousel", "redirect", "carousel"), "a");
            Assert.AreEqual(-1, c.OnProp);
            Assert.AreEqual(0, c.Turn());
            Assert.AreEqual(2, c.Turn());
            Assert.AreEqual(4, c.Turn());
            Assert.AreEqual(0, c.Turn());
            Assert.AreEqual(2, c.BringOn(4));
            Assert.AreEqual(0, c.BringOn(4));
            Assert.AreEqual(-1, c.BringOn(1));
            Assert.AreEqual(-1, new Carousel(File("redirect"), "a").Turn());
        }

        [TestCase(new[] { 0.03, 0.05, 0.02, 0.04 }, 0.12, 0.02)]
        [TestCase(new[] { 0.08, 0.08, 0.08, 0.08, 0.08, 0.08, 0.08, 0.08 }, 0.12, 0.02)]
        [TestCase(new[] { 0.2, 0.01 }, 0.05, 0.01)]
        public void NeighboursOnTheRingNeverTouch(double[] radii, double least, double gap)
        {
            double[] angles;
            double radius = Carousel.Ring(radii, least, gap, out angles);
            Assert.GreaterOrEqual(radius, least);
            int n = radii.Length;
            for (int i = 0; i < n; i++)
            {
                int j = (i + 1) % n;
                double chord = 2 * radius * Math.Sin(Math.Abs(angles[j] - angles[i]) / 2);
                if (j == 0) chord = 2 * radius * Math.Sin((2 * Math.PI - angles[i]) / 2);
                Assert.GreaterOrEqual(chord + 1e-12, radii[i] + radii[j] + gap);
            }
            Assert.AreEqual(0.0, angles[0]);
        }

        [Test]
        public void OneObjectSitsAtTheRingsStart()
        {
            double[] angles;
            double radius = Carousel.Ring(new[] { 0.3 }, 0.12, 0.02, out angles);
            Assert.AreEqual(0.32, radius, 1e-12);
            CollectionAssert.AreEqual(new[] { 0.0 }, angles);
        }
    }

    [TestFixture]
    public class ValidationTests
    {
        static readonly Vec3[] Targets = { new Vec3(0.10, 0.90, 0.00), new Vec3(0.05, 0.90, 0.02) };

        [Test]
        public void AGraspOnItsTargetsPassesInEitherFingerOrder()
        {
            var ok = Validation.Check(new[] { Targets[0], Targets[1] }, Targets, Limits.Study);
            Assert.IsTrue(ok.Ok);
            Assert.AreEqual("thumb on p1", ok.Order);
            var swapped = Validation.Check(new[] { Targets[1], Targets[0] }, Targets, Limits.Study);
            Assert.IsTrue(swapped.Ok);
            Assert.AreEqual("thumb on p2", swapped.Order);
        }

        [TestCase(0.0049, true)]
        [TestCase(0.0051, false)]
        public void AFingertipMustBeWithinFiveMillimetres(double off, bool ok)
        {
            // off along the pinch line, so the direction does not change
            var line = (Targets[1] - Targets[0]).Normalized;
            var check = Validation.Check(new[] { Targets[0] - line * off, Targets[1] }, Targets, Limits.Study);
            Assert.AreEqual(ok, check.Ok);
            Assert.AreEqual(off * 1000, check.ErrorsMm[0], 1e-9);
        }

        [Test]
        public void TheGraspsDirectionMustBeWithinFourteenDegrees()
        {
            // both fingertips 4.5 mm off, in opposite directions across the 54 mm line: 9.5 degrees
            var line = Targets[1] - Targets[0];
            var across = Vec3.Cross(line, new Vec3(0, 1, 0)).Normalized;
            var small = Validation.Check(new[] { Targets[0] - across * 0.0045, Targets[1] + across * 0.0045 }, Targets, Limits.Study);
            Assert.IsTrue(small.Ok);
            Assert.AreEqual(Math.Atan(0.009 / line.Length) * 180 / Math.PI, small.AngleErrorDeg, 1e-9);
            var wide = Validation.Check(new[] { Targets[0] - across * 0.0045, Targets[1] + across * 0.0045 }, Targets,
                                        new Limits(5, 9, 1));
            Assert.IsFalse(wide.Ok);
        }

        [Test]
        public void ATripodsFingersMayTakeEitherOfTheirTargets()
        {
            var t = new[] { new Vec3(0, 0.9, 0), new Vec3(0.04, 0.9, 0.01), new Vec3(0.04, 0.9, -0.02) };
            var check = Validation.Check(new[] { t[0], t[2], t[1] }, t, Limits.Study);
            Assert.IsTrue(check.Ok);
            Assert.AreEqual("index on the third target", check.Order);
            Assert.AreEqual(3, check.ErrorsMm.Length);
            Assert.Throws<ArgumentException>(() => Validation.Check(new[] { t[0], t[1] }, t, Limits.Study));
            Assert.Throws<ArgumentException>(() => Validation.Check(t, new[] { t[0] }, Limits.Study));
        }

        [Test]
        public void AGraspHeldASecondIsValidatedABreakStartsAgain()
        {
            var timer = new HoldTimer(1.0);
            Assert.AreEqual(0.0, timer.Update(true, 10.0));
            Assert.AreEqual(0.5, timer.Update(true, 10.5), 1e-12);
            Assert.AreEqual(0.0, timer.Update(false, 10.6));
            timer.Update(true, 11.0);
            Assert.IsFalse(timer.Validated);
            timer.Update(true, 12.0);
            Assert.IsTrue(timer.Validated);
            Assert.AreEqual(1.0, timer.Update(false, 12.5));
            timer.Reset();
            Assert.IsFalse(timer.Validated);
        }
    }

    [TestFixture]
    public class ToolkitTests
    {
        [Test]
        public void TheAttachPoseFacesAlongTheReachItsRightAlongTheGrasp()
        {
            var rng = new Random(31);
            for (int k = 0; k < 20; k++)
            {
                var tips = new[] { Fixtures.RandomVec(rng, 0.5), Fixtures.RandomVec(rng, 0.5) };
                var approach = Fixtures.RandomVec(rng, 1).Normalized;
                var attach = Toolkits.Attach(tips, approach);
                Fixtures.Near(Vec3.Centroid(tips), attach.Position, 1e-15);
                Fixtures.Near(-approach, attach.Rotation * new Vec3(0, 0, 1), 1e-9);
                var right = attach.Rotation * new Vec3(1, 0, 0);
                var line = tips[1] - tips[0];
                Assert.AreEqual(0.0, Vec3.Dot(right, approach), 1e-9);
                Assert.Greater(Vec3.Dot(right, line), 0.0);
                Assert.AreEqual(1.0, Mat3.Of(attach.Rotation).Determinant, 1e-9);
            }
        }

        [Test]
        public void AGraspAlongItsApproachStillHasAnAttachPose()
        {
            var attach = Toolkits.Attach(new[] { new Vec3(0, 0, 0), new Vec3(0, 0.05, 0) }, new Vec3(0, 1, 0));
            Fixtures.Near(new Vec3(0, -1, 0), attach.Rotation * new Vec3(0, 0, 1), 1e-12);
            Assert.AreEqual(1.0, attach.Rotation.Norm, 1e-12);
        }

        [Test]
        public void HartsPairsComeCheapestFirst()
        {
            var tips = new[] { new Target("ThumbTip", new Vec3(0, 1, 0)), new Target("IndexTip", new Vec3(0.05, 1, 0)) };
            var placed = new[] { 0.9, 0.3, 0.3, 1.2 }.Select(c => new Placed
            {
                Cost = c, Mode = "registered", Fingertips = tips, SeenFingertips = tips, Approach = new Vec3(0, 1, 0),
            }).ToList();
            var pairs = Toolkits.HartPairs(placed);
            CollectionAssert.AreEqual(new[] { 0.3, 0.3, 0.9, 1.2 }, pairs.Select(p => p.Cost).ToArray());
            // an object shown on the prop: the seen target is the real one
            Fixtures.Near(pairs[0].Real.Position, pairs[0].Virtual.Position, 0);
        }

        [Test]
        public void ARedirectedPairSeesTheLevelsGraspAndReachesTheProps()
        {
            var real = new[] { new Target("ThumbTip", new Vec3(0.1, 0.8, -0.2)), new Target("IndexTip", new Vec3(0.12, 0.8, -0.25)) };
            var seen = new[] { new Target("ThumbTip", new Vec3(-0.47, 0.93, -0.2)), new Target("IndexTip", new Vec3(-0.46, 0.93, -0.26)) };
            var pair = Toolkits.Pair(new Placed { Mode = "redirect", Fingertips = real, SeenFingertips = seen, Cost = 1 });
            Fixtures.Near(new Vec3(0.11, 0.8, -0.225), pair.Real.Position, 1e-12);
            Fixtures.Near(new Vec3(-0.465, 0.93, -0.23), pair.Virtual.Position, 1e-12);
        }
    }
}
