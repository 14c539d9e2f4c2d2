using System;
using NUnit.Framework;
using Pinchmatch;

namespace Pinchmatch.Tests
{
    [TestFixture]
    public class FramesTests
    {
        [TestCase(5)]
        [TestCase(6)]
        [TestCase(7)]
        public void AMirroredQuaternionTurnsMirroredPointsAsTheGltfOneTurnedTheOriginals(int seed)
        {
            var rng = new Random(seed);
            var q = Fixtures.RandomRotation(rng);
            var p = Fixtures.RandomVec(rng, 2);
            var inGltf = q * p;
            Fixtures.Near(Frames.GltfToUnity(inGltf), Frames.GltfToUnity(q) * Frames.GltfToUnity(p), 1e-12);
        }

        [Test]
        public void TheQuaternionRuleIsTheMatrixConjugation()
        {
            var rng = new Random(9);
            var q = Fixtures.RandomRotation(rng);
            var S = Frames.GltfToUnityMap.A;
            var expected = (S * Mat3.Of(q) * S).ToQuat();
            Assert.Less(Quat.AngleDeg(expected, Frames.GltfToUnity(q)), 1e-9);
        }

        [TestCase(1)]
        [TestCase(2)]
        [TestCase(3)]
        public void TheSmallestRotationTakesOneDirectionOntoTheOther(int seed)
        {
            var rng = new Random(seed);
            var a = Fixtures.RandomVec(rng, 1).Normalized;
            var b = Fixtures.RandomVec(rng, 1).Normalized;
            var R = Frames.RotationBetween(a, b);
            Fixtures.Near(b, R.Apply(a), 1e-12);
            Assert.AreEqual(1.0, R.Determinant, 1e-12);
            // smallest: the axis a x b is kept
            var axis = Vec3.Cross(a, b);
            Fixtures.Near(axis, R.Apply(axis), 1e-12);
        }

        [Test]
        public void OppositeDirectionsGetTheHalfTurnPinchmatchChooses()
        {
            // -Y onto +Y: about -Y x X = (0, 0, 1), a half turn about Z
            var R = Frames.RotationBetween(new Vec3(0, -1, 0), new Vec3(0, 1, 0));
            Fixtures.Near(new Vec3(-1, 0, 0), R.Apply(new Vec3(1, 0, 0)), 1e-12);
            Fixtures.Near(new Vec3(0, 0, 1), R.Apply(new Vec3(0, 0, 1)), 1e-12);
            // -X onto +X: -X x X is zero, so about -X x Y = (0, 0, -1)
            var R2 = Frames.RotationBetween(new Vec3(-1, 0, 0), new Vec3(1, 0, 0));
            Fixtures.Near(new Vec3(0, -1, 0), R2.Apply(new Vec3(0, 1, 0)), 1e-12);
        }

        [Test]
        public void AZUpFileMapsItsUpOntoGltfsUpInMetres()
        {
            var C = Frames.FileMmToGltfM(Fixtures.ZUp);
            Fixtures.Near(new Vec3(0, 0.001, 0), C.Point(new Vec3(0, 0, 1)), 1e-15);
            // the smallest such turn is about X: file -Y goes to glTF +Z... (x stays)
            Fixtures.Near(new Vec3(0.001, 0, 0), C.Point(new Vec3(1, 0, 0)), 1e-15);
            Fixtures.Near(new Vec3(0, 0, -0.001), C.Point(new Vec3(0, 1, 0)), 1e-15);
        }

        [Test]
        public void AYUpFileInUnityIsOnlyMirroredAndScaled()
        {
            var B = Frames.FileMmToUnity(Fixtures.YUp);
            Fixtures.Near(new Vec3(-0.012, 0.034, 0.056), B.Point(new Vec3(12, 34, 56)), 1e-15);
            Assert.AreEqual(-1e-9, B.A.Determinant, 1e-18);
        }

        [Test]
        public void DirectionsStayUnit()
        {
            var d = Frames.FileDirectionToUnity(Fixtures.ZUp, new Vec3(0.6, 0, 0.8));
            Assert.AreEqual(1.0, d.Length, 1e-12);
            Fixtures.Near(new Vec3(-0.6, 0.8, 0), d, 1e-12);
        }

        [Test]
        public void APoseSurvivesTheTripToUnityAndBack()
        {
            var rng = new Random(12);
            var p = new Pose(Fixtures.RandomVec(rng, 1), Fixtures.RandomRotation(rng));
            var back = new Pose(Frames.UnityToGltf(Frames.GltfToUnity(p).Position),
                                Frames.UnityToGltf(Frames.GltfToUnity(p).Rotation));
            Fixtures.Near(p.Position, back.Position, 0);
            Assert.Less(Quat.AngleDeg(p.Rotation, back.Rotation), 1e-12);
        }
    }
}
