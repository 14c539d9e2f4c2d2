// Double-precision vectors, quaternions, 4x4 matrices and rigid poses, free of any engine type.
// Quaternions are (x, y, z, w), Hamilton's convention, acting on column vectors: v' = q v q*.
using System;

namespace Pinchmatch
{
    /// <summary>A 3-vector of doubles.</summary>
    public struct Vec3
    {
        public double X, Y, Z;

        public Vec3(double x, double y, double z) { X = x; Y = y; Z = z; }

        public static readonly Vec3 Zero = new Vec3(0, 0, 0);

        public static Vec3 operator +(Vec3 a, Vec3 b) { return new Vec3(a.X + b.X, a.Y + b.Y, a.Z + b.Z); }
        public static Vec3 operator -(Vec3 a, Vec3 b) { return new Vec3(a.X - b.X, a.Y - b.Y, a.Z - b.Z); }
        public static Vec3 operator -(Vec3 a) { return new Vec3(-a.X, -a.Y, -a.Z); }
        public static Vec3 operator *(Vec3 a, double s) { return new Vec3(a.X * s, a.Y * s, a.Z * s); }
        public static Vec3 operator *(double s, Vec3 a) { return a * s; }
        public static Vec3 operator /(Vec3 a, double s) { return new Vec3(a.X / s, a.Y / s, a.Z / s); }

        public static double Dot(Vec3 a, Vec3 b) { return a.X * b.X + a.Y * b.Y + a.Z * b.Z; }

        public static Vec3 Cross(Vec3 a, Vec3 b)
        {
            return new Vec3(a.Y * b.Z - a.Z * b.Y, a.Z * b.X - a.X * b.Z, a.X * b.Y - a.Y * b.X);
        }

        public double Length { get { return Math.Sqrt(Dot(this, this)); } }

        /// <summary>This vector scaled to length 1 (zero stays zero).</summary>
        public Vec3 Normalized
        {
            get { double n = Length; return n > 0 ? this / n : this; }
        }

        public double this[int i]
        {
            get { return i == 0 ? X : i == 1 ? Y : Z; }
        }

        /// <summary>The angle between two vectors, degrees (0 where either is zero).</summary>
        public static double AngleDeg(Vec3 a, Vec3 b)
        {
            double n = a.Length * b.Length;
            if (!(n > 0)) return 0;
            double c = Math.Max(-1.0, Math.Min(1.0, Dot(a, b) / n));
            return Math.Acos(c) * 180.0 / Math.PI;
        }

        /// <summary>The mean of the points (zero for none).</summary>
        public static Vec3 Centroid(Vec3[] points)
        {
            var sum = Zero;
            foreach (var p in points) sum = sum + p;
            return points.Length > 0 ? sum / points.Length : sum;
        }

        public double[] ToArray() { return new[] { X, Y, Z }; }

        public override string ToString() { return "(" + X + ", " + Y + ", " + Z + ")"; }
    }

    /// <summary>A rotation as a unit quaternion (x, y, z, w).</summary>
    public struct Quat
    {
        public double X, Y, Z, W;

        public Quat(double x, double y, double z, double w) { X = x; Y = y; Z = z; W = w; }

        public static readonly Quat Identity = new Quat(0, 0, 0, 1);

        /// <summary>The Hamilton product: the rotation b, then a.</summary>
        public static Quat operator *(Quat a, Quat b)
        {
            return new Quat(a.W * b.X + a.X * b.W + a.Y * b.Z - a.Z * b.Y,
                            a.W * b.Y - a.X * b.Z + a.Y * b.W + a.Z * b.X,
                            a.W * b.Z + a.X * b.Y - a.Y * b.X + a.Z * b.W,
                            a.W * b.W - a.X * b.X - a.Y * b.Y - a.Z * b.Z);
        }

        public static Vec3 operator *(Quat q, Vec3 v) { return Mat3.Of(q).Apply(v); }

        public Quat Conjugate { get { return new Quat(-X, -Y, -Z, W); } }

        public double Norm { get { return Math.Sqrt(X * X + Y * Y + Z * Z + W * W); } }

        public Quat Normalized
        {
            get { double n = Norm; return new Quat(X / n, Y / n, Z / n, W / n); }
        }

        /// <summary>The rotation of angleDeg degrees about an axis.</summary>
        public static Quat AxisAngle(Vec3 axis, double angleDeg)
        {
            var u = axis.Normalized;
            double h = angleDeg * Math.PI / 360.0, s = Math.Sin(h);
            return new Quat(u.X * s, u.Y * s, u.Z * s, Math.Cos(h));
        }

        /// <summary>The angle between two rotations, degrees (0 to 180; q and -q are one rotation).</summary>
        public static double AngleDeg(Quat a, Quat b)
        {
            double d = Math.Abs(a.X * b.X + a.Y * b.Y + a.Z * b.Z + a.W * b.W) / (a.Norm * b.Norm);
            return 2.0 * Math.Acos(Math.Min(1.0, d)) * 180.0 / Math.PI;
        }

        public double[] ToArray() { return new[] { X, Y, Z, W }; }

        public override string ToString() { return "(" + X + ", " + Y + ", " + Z + ", " + W + ")"; }
    }

    /// <summary>A 3x3 matrix, row-major.</summary>
    public struct Mat3
    {
        public double M00, M01, M02, M10, M11, M12, M20, M21, M22;

        public static Mat3 Rows(Vec3 r0, Vec3 r1, Vec3 r2)
        {
            return new Mat3 { M00 = r0.X, M01 = r0.Y, M02 = r0.Z, M10 = r1.X, M11 = r1.Y, M12 = r1.Z,
                              M20 = r2.X, M21 = r2.Y, M22 = r2.Z };
        }

        public static Mat3 Columns(Vec3 c0, Vec3 c1, Vec3 c2) { return Rows(c0, c1, c2).Transposed; }

        public static readonly Mat3 Identity = Rows(new Vec3(1, 0, 0), new Vec3(0, 1, 0), new Vec3(0, 0, 1));

        public Vec3 Apply(Vec3 v)
        {
            return new Vec3(M00 * v.X + M01 * v.Y + M02 * v.Z, M10 * v.X + M11 * v.Y + M12 * v.Z,
                            M20 * v.X + M21 * v.Y + M22 * v.Z);
        }

        public Mat3 Transposed
        {
            get
            {
                return new Mat3 { M00 = M00, M01 = M10, M02 = M20, M10 = M01, M11 = M11, M12 = M21,
                                  M20 = M02, M21 = M12, M22 = M22 };
            }
        }

        public double Determinant
        {
            get
            {
                return M00 * (M11 * M22 - M12 * M21) - M01 * (M10 * M22 - M12 * M20)
                       + M02 * (M10 * M21 - M11 * M20);
            }
        }

        public static Mat3 operator *(Mat3 a, Mat3 b)
        {
            var c0 = a.Apply(new Vec3(b.M00, b.M10, b.M20));
            var c1 = a.Apply(new Vec3(b.M01, b.M11, b.M21));
            var c2 = a.Apply(new Vec3(b.M02, b.M12, b.M22));
            return Columns(c0, c1, c2);
        }

        public static Mat3 Scale(double s) { return Rows(new Vec3(s, 0, 0), new Vec3(0, s, 0), new Vec3(0, 0, s)); }

        /// <summary>The rotation matrix of a unit quaternion.</summary>
        public static Mat3 Of(Quat q)
        {
            double x = q.X, y = q.Y, z = q.Z, w = q.W;
            return Rows(new Vec3(1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
                        new Vec3(2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
                        new Vec3(2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)));
        }

        /// <summary>The unit quaternion of a rotation matrix (Shepperd's method), w >= 0.</summary>
        public Quat ToQuat()
        {
            double tr = M00 + M11 + M22;
            Quat q;
            if (tr > 0)
            {
                double s = Math.Sqrt(tr + 1.0) * 2;
                q = new Quat((M21 - M12) / s, (M02 - M20) / s, (M10 - M01) / s, 0.25 * s);
            }
            else if (M00 > M11 && M00 > M22)
            {
                double s = Math.Sqrt(1.0 + M00 - M11 - M22) * 2;
                q = new Quat(0.25 * s, (M01 + M10) / s, (M02 + M20) / s, (M21 - M12) / s);
            }
            else if (M11 > M22)
            {
                double s = Math.Sqrt(1.0 + M11 - M00 - M22) * 2;
                q = new Quat((M01 + M10) / s, 0.25 * s, (M12 + M21) / s, (M02 - M20) / s);
            }
            else
            {
                double s = Math.Sqrt(1.0 + M22 - M00 - M11) * 2;
                q = new Quat((M02 + M20) / s, (M12 + M21) / s, 0.25 * s, (M10 - M01) / s);
            }
            q = q.Normalized;
            return q.W < 0 ? new Quat(-q.X, -q.Y, -q.Z, -q.W) : q;
        }
    }

    /// <summary>An affine map x -> A x + t (A any 3x3: a rotation, a scale, a mirror).</summary>
    public struct Affine
    {
        public Mat3 A;
        public Vec3 T;

        public Affine(Mat3 a, Vec3 t) { A = a; T = t; }

        public static readonly Affine Identity = new Affine(Mat3.Identity, Vec3.Zero);

        public Vec3 Point(Vec3 p) { return A.Apply(p) + T; }

        public Vec3 Direction(Vec3 d) { return A.Apply(d); }

        /// <summary>The map b, then a.</summary>
        public static Affine operator *(Affine a, Affine b)
        {
            return new Affine(a.A * b.A, a.A.Apply(b.T) + a.T);
        }

        /// <summary>The inverse map (A must be invertible: cofactors over the determinant).</summary>
        public Affine Inverse
        {
            get
            {
                var m = A;
                double det = m.Determinant;
                if (Math.Abs(det) < 1e-300) throw new InvalidOperationException("a singular map");
                var inv = new Mat3
                {
                    M00 = (m.M11 * m.M22 - m.M12 * m.M21) / det, M01 = (m.M02 * m.M21 - m.M01 * m.M22) / det,
                    M02 = (m.M01 * m.M12 - m.M02 * m.M11) / det, M10 = (m.M12 * m.M20 - m.M10 * m.M22) / det,
                    M11 = (m.M00 * m.M22 - m.M02 * m.M20) / det, M12 = (m.M02 * m.M10 - m.M00 * m.M12) / det,
                    M20 = (m.M10 * m.M21 - m.M11 * m.M20) / det, M21 = (m.M01 * m.M20 - m.M00 * m.M21) / det,
                    M22 = (m.M00 * m.M11 - m.M01 * m.M10) / det,
                };
                return new Affine(inv, -inv.Apply(T));
            }
        }

        /// <summary>A 4x4 matrix of 16 numbers row by row (pinchmatch's JSON) or column by column
        /// (glTF's "matrix").</summary>
        public static Affine FromRowMajor(double[] m)
        {
            if (m.Length != 16) throw new ArgumentException("a 4x4 matrix needs 16 numbers");
            return new Affine(Mat3.Rows(new Vec3(m[0], m[1], m[2]), new Vec3(m[4], m[5], m[6]),
                                        new Vec3(m[8], m[9], m[10])), new Vec3(m[3], m[7], m[11]));
        }

        public static Affine FromColumnMajor(double[] m)
        {
            if (m.Length != 16) throw new ArgumentException("a 4x4 matrix needs 16 numbers");
            return new Affine(Mat3.Columns(new Vec3(m[0], m[1], m[2]), new Vec3(m[4], m[5], m[6]),
                                           new Vec3(m[8], m[9], m[10])), new Vec3(m[12], m[13], m[14]));
        }

        /// <summary>glTF's translation, rotation and scale: T * R * S.</summary>
        public static Affine Trs(Vec3 t, Quat r, Vec3 s)
        {
            var R = Mat3.Of(r);
            var S = Mat3.Rows(new Vec3(s.X, 0, 0), new Vec3(0, s.Y, 0), new Vec3(0, 0, s.Z));
            return new Affine(R * S, t);
        }

        public static Affine Of(Pose pose) { return new Affine(Mat3.Of(pose.Rotation), pose.Position); }
    }

    /// <summary>A rigid pose: a position and a rotation, the map x -> R x + p.</summary>
    public struct Pose
    {
        public Vec3 Position;
        public Quat Rotation;

        public Pose(Vec3 position, Quat rotation) { Position = position; Rotation = rotation; }

        public static readonly Pose Identity = new Pose(Vec3.Zero, Quat.Identity);

        public Vec3 Point(Vec3 p) { return Rotation * p + Position; }

        /// <summary>The pose b, then a (a * b as transforms: a's frame holds b).</summary>
        public static Pose operator *(Pose a, Pose b)
        {
            return new Pose(a.Point(b.Position), (a.Rotation * b.Rotation).Normalized);
        }

        public Pose Inverse
        {
            get
            {
                var r = Rotation.Conjugate;
                return new Pose(-(r * Position), r);
            }
        }

        /// <summary>The pose of a rigid affine map (its A a rotation, det +1 within 1e-6).</summary>
        public static Pose Of(Affine m)
        {
            double det = m.A.Determinant;
            if (Math.Abs(det - 1.0) > 1e-6)
                throw new ArgumentException("not a rotation: det " + det);
            return new Pose(m.T, m.A.ToQuat());
        }
    }
}
