// Pinocchio's own code generation (CppADCodeGen) for the speed benchmark: reads a robot from a model file
// written by codegen/peers/cppadcg.py and writes the C sources CppADCodeGen generates for Pinocchio's
// CodeGenRNEA, CodeGenABA (each with its Jacobian in (q, v, a|tau)), CodeGenRNEADerivatives,
// CodeGenABADerivatives and, in the same style, computeJointTorqueRegressor. The sources are compiled
// into the benchmark harness with its flags. Compiled once per benchmark run, run once per robot.
//
// Usage: cppadcg_gen MODEL_FILE OUT_FOLDER
// Model file: "njoints", then per joint "parent shortname axis(3) rotation(9, row-major) translation(3)
// mass lever(3) inertia(9)", then "armature(nv)" and "gravity(3)".
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>

#include <pinocchio/codegen/cppadcg-algo.hpp>
#include <pinocchio/algorithm/regressor.hpp>

template <int N>
static Eigen::Matrix<double, N, 1> read_vector(std::istream& in) {
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) in >> v[i];
  return v;
}

static pinocchio::JointModel make_joint(const std::string& shortname, const Eigen::Vector3d& axis) {
  if (shortname == "JointModelRX") return pinocchio::JointModelRX();
  if (shortname == "JointModelRY") return pinocchio::JointModelRY();
  if (shortname == "JointModelRZ") return pinocchio::JointModelRZ();
  if (shortname == "JointModelPX") return pinocchio::JointModelPX();
  if (shortname == "JointModelPY") return pinocchio::JointModelPY();
  if (shortname == "JointModelPZ") return pinocchio::JointModelPZ();
  if (shortname == "JointModelRevoluteUnaligned") return pinocchio::JointModelRevoluteUnaligned(axis);
  if (shortname == "JointModelPrismaticUnaligned") return pinocchio::JointModelPrismaticUnaligned(axis);
  throw std::runtime_error("joint type " + shortname + " is not supported by the CppADCodeGen peer");
}

static pinocchio::Model read_model(const char* path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(std::string("cannot read ") + path);
  pinocchio::Model model;
  int njoints = 0;
  in >> njoints;
  for (int j = 1; j < njoints; ++j) {
    int parent;
    std::string shortname;
    in >> parent >> shortname;
    Eigen::Vector3d axis = read_vector<3>(in);
    Eigen::Matrix<double, 9, 1> r = read_vector<9>(in);
    Eigen::Matrix3d rotation;
    rotation << r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8];
    Eigen::Vector3d translation = read_vector<3>(in);
    double mass;
    in >> mass;
    Eigen::Vector3d lever = read_vector<3>(in);
    Eigen::Matrix<double, 9, 1> i9 = read_vector<9>(in);
    Eigen::Matrix3d inertia;
    inertia << i9[0], i9[1], i9[2], i9[3], i9[4], i9[5], i9[6], i9[7], i9[8];
    pinocchio::JointIndex jid = model.addJoint(
        parent, make_joint(shortname, axis), pinocchio::SE3(rotation, translation), "joint" + std::to_string(j));
    model.inertias[jid] = pinocchio::Inertia(mass, lever, inertia);
  }
  model.armature = Eigen::VectorXd(model.nv);
  for (int i = 0; i < model.nv; ++i) in >> model.armature[i];
  model.gravity.linear(read_vector<3>(in));
  if (!in) throw std::runtime_error(std::string("malformed model file ") + path);
  return model;
}

// The joint torque regressor, taped like Pinocchio's CodeGenRNEA (no CodeGen class ships for it).
template <typename _Scalar>
struct CodeGenRegressor : public pinocchio::CodeGenBase<_Scalar> {
  typedef pinocchio::CodeGenBase<_Scalar> Base;
  CodeGenRegressor(const typename Base::Model& model, const std::string& name)
      : Base(model, model.nq + 2 * model.nv, model.nv * 10 * (model.njoints - 1), name, "cg_regressor") {}
  void buildMap() {
    CppAD::Independent(this->ad_X);
    const auto& m = this->ad_model;
    typename Base::ADConfigVectorType q = this->ad_X.segment(0, m.nq);
    typename Base::ADTangentVectorType v = this->ad_X.segment(m.nq, m.nv);
    typename Base::ADTangentVectorType a = this->ad_X.segment(m.nq + m.nv, m.nv);
    pinocchio::computeJointTorqueRegressor(m, this->ad_data, q, v, a);
    Eigen::Map<typename Base::ADMatrixXs>(this->ad_Y.data(), m.nv, 10 * (m.njoints - 1)) =
        this->ad_data.jointTorqueRegressor;
    this->ad_fun.Dependent(this->ad_X, this->ad_Y);
    this->ad_fun.optimize("no_compare_op");
  }
};

// A Pinocchio CodeGen object with its sources generated (the Jacobian only when asked).
template <class Base>
struct Generated : Base {
  Generated(const pinocchio::Model& model, const char* name, bool jacobian) : Base(model, name) {
    this->build_jacobian = jacobian;
    this->initLib();
  }
};

// Writes a model's generated C files (ModelLibraryCSourceGen::saveSources does not compile in this CppADCodeGen).
struct Saver : CppAD::cg::ModelLibraryProcessor<double> {
  using CppAD::cg::ModelLibraryProcessor<double>::ModelLibraryProcessor;
  void save(CppAD::cg::ModelCSourceGen<double>& model, const std::string& folder) {
    for (const auto& source : getSources(model)) {
      std::ofstream out(folder + "/" + source.first);
      out << source.second;
    }
  }
};

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: cppadcg_gen MODEL_FILE OUT_FOLDER\n";
    return 2;
  }
  try {
    pinocchio::Model model = read_model(argv[1]);
    Generated<pinocchio::CodeGenRNEA<double>> rnea(model, "rnea", true);
    Generated<pinocchio::CodeGenABA<double>> aba(model, "aba", true);
    Generated<pinocchio::CodeGenRNEADerivatives<double>> rnea_derivatives(model, "rnea_derivatives", false);
    Generated<pinocchio::CodeGenABADerivatives<double>> aba_derivatives(model, "aba_derivatives", false);
    Generated<CodeGenRegressor<double>> regressor(model, "regressor", false);
    CppAD::cg::ModelLibraryCSourceGen<double> library(rnea.codeGenerator(), aba.codeGenerator());
    library.addModel(rnea_derivatives.codeGenerator());
    library.addModel(aba_derivatives.codeGenerator());
    library.addModel(regressor.codeGenerator());
    Saver saver(library);
    for (auto* generated : {&rnea.codeGenerator(), &aba.codeGenerator(), &rnea_derivatives.codeGenerator(),
                            &aba_derivatives.codeGenerator(), &regressor.codeGenerator()})
      saver.save(*generated, argv[2]);
  } catch (const std::exception& error) {
    std::cerr << "cppadcg_gen: " << error.what() << "\n";
    return 1;
  }
  return 0;
}
