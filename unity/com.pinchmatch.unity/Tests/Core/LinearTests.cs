using System;
using NUnit.Framework;
using Pinchmatch;

namespace Pinchmatch.Tests
{
    [TestFixture]
    public class LinearTests
    {
        [TestCase(1)]
        [TestCase(2)]
        [TestCase(3)]
        [TestCase(4)]
        public void AQuaternionSurvivesItsMatrix(int seed)
        {
            var rng = new Random(seed);
            for (int k = 0; k < 50; k++)
            {
                var q = Fixtures.RandomRotation(rng);
                var back = Mat3.Of(q).ToQuat();
                Assert.Less(Quat.AngleDeg(q, back), 1e-9);
                Assert.GreaterOrEqual(back.W, 0.0);
            }
        }

        [Test]
        public void TheProductTurnsByTheRightOneFirst()
        {
            var rng = new Random(7);
            var a = Fixtures.RandomRotation(rng);
            var b = Fixtures.RandomRotation(rng);
            var v = new Vec3(0.3, -1.2, 2.0);
            Fixtures.Near(a * (b * v), (a * b) * v, 1e-12);
            Fixtures.Near(Mat3.Of(a).Apply(Mat3.Of(b).Apply(v)), (Mat3.Of(a) * Mat3.Of(b)).Apply(v), 1e-12);
        }

        [Test]
        public void AnAffineMapWithAMirrorAndAScaleInverts()
        {
            var rng = new Random(3);
            var m = new Affine(Mat3.Of(Fixtures.RandomRotation(rng)) * Frames.GltfToUnityMap.A * Mat3.Scale(0.001),
                               new Vec3(1, 2, 3));
            var p = new Vec3(40, -70, 12);
            Fixtures.Near(p, m.Inverse.Point(m.Point(p)), 1e-9);
            Fixtures.Near(p, (m * m.Inverse).Point(p), 1e-12);
        }

        [Test]
        public void APoseComposesAndInverts()
        {
            var rng = new Random(11);
            var a = new Pose(new Vec3(1, -2, 0.5), Fixtures.RandomRotation(rng));
            var b = new Pose(new Vec3(-0.3, 0.2, 4), Fixtures.RandomRotation(rng));
            var p = new Vec3(0.7, 0.1, -0.9);
            Fixtures.Near(a.Point(b.Point(p)), (a * b).Point(p), 1e-12);
            Fixtures.Near(p, a.Inverse.Point(a.Point(p)), 1e-12);
        }

        [Test]
        public void RowAndColumnMajorAreEachOthersTranspose()
        {
            var numbers = new double[16];
            for (int i = 0; i < 16; i++) numbers[i] = i + 1;
            var rows = Affine.FromRowMajor(numbers);
            var columns = Affine.FromColumnMajor(numbers);
            Assert.AreEqual(2.0, rows.A.M01);
            Assert.AreEqual(5.0, columns.A.M01);
            Assert.AreEqual(4.0, rows.T.X);
            Assert.AreEqual(13.0, columns.T.X);
        }

        [Test]
        public void TrsScalesThenTurnsThenMoves()
        {
            var q = Quat.AxisAngle(new Vec3(0, 0, 1), 90);
            var m = Affine.Trs(new Vec3(10, 0, 0), q, new Vec3(2, 1, 1));
            Fixtures.Near(new Vec3(10, 2, 0), m.Point(new Vec3(1, 0, 0)), 1e-12);
        }

        [Test]
        public void APoseIsNeverMadeOfAMirror()
        {
            Assert.Throws<ArgumentException>(() => Pose.Of(Frames.GltfToUnityMap));
        }

        [Test]
        public void AnglesAreInDegrees()
        {
            Assert.AreEqual(90.0, Vec3.AngleDeg(new Vec3(1, 0, 0), new Vec3(0, 0, 2)), 1e-12);
            Assert.AreEqual(30.0, Quat.AngleDeg(Quat.Identity, Quat.AxisAngle(new Vec3(1, 1, 0), 30)), 1e-9);
        }
    }
}
